/* Loops of APE's alignment and translation error over (n, 3) float64 position arrays (any strides),
   in one pass each, without the GIL: the fast path of geometry/point_fit.py (Umeyama) and evaluation/ape.py.

   Every sum and product is done in the order and with the roundings of the numpy code it replaces
   (which holds evo's bits): sums strictly sequential from 0.0; no FMA contraction (-ffp-contract=off
   and the pragma below), so each IEEE operation rounds on its own. tests/evaluation/
   test_alignment_kernels.py holds both to the same bits. Without a compiler numpy does the work. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("fp-contract=off")
#endif
#if defined(__clang__)
#pragma clang fp contract(off)
#endif

typedef struct {
    Py_buffer view;
    Py_ssize_t n, row, col; /* rows; strides in doubles */
    const char *base;
} Points;

/* An (n, 3) float64 buffer with strides that are whole doubles; 0, or -1 with an exception set. */
static int get_points(PyObject *obj, Points *p, int writable) {
    if (PyObject_GetBuffer(obj, &p->view, PyBUF_STRIDES | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0)) != 0)
        return -1;
    Py_buffer *v = &p->view;
    if (v->ndim != 2 || v->shape[1] != 3 || v->itemsize != 8 || v->format == NULL || strcmp(v->format, "d") != 0 ||
        v->strides[0] % 8 != 0 || v->strides[1] % 8 != 0) {
        PyBuffer_Release(v);
        PyErr_SetString(PyExc_ValueError, "expected an (n, 3) float64 array");
        return -1;
    }
    p->n = v->shape[0];
    p->row = v->strides[0] / 8;
    p->col = v->strides[1] / 8;
    p->base = v->buf;
    return 0;
}

#define AT(p, i, j) (((const double *)(p).base)[(i) * (p).row + (j) * (p).col])

static PyObject *column_sums(PyObject *self, PyObject *arg) {
    (void)self;
    Points a;
    if (get_points(arg, &a, 0) != 0) return NULL;
    double s0 = 0.0, s1 = 0.0, s2 = 0.0;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < a.n; i++) {
        s0 += AT(a, i, 0);
        s1 += AT(a, i, 1);
        s2 += AT(a, i, 2);
    }
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&a.view);
    return Py_BuildValue("(ddd)", s0, s1, s2);
}

/* sum_i (y_i - my)(x_i - mx)^T, row-major 3x3, each entry added point after point. */
static PyObject *centred_outer_sum(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *yo, *xo;
    double my[3], mx[3];
    if (!PyArg_ParseTuple(args, "O(ddd)O(ddd)", &yo, &my[0], &my[1], &my[2], &xo, &mx[0], &mx[1], &mx[2]))
        return NULL;
    Points y, x;
    if (get_points(yo, &y, 0) != 0) return NULL;
    if (get_points(xo, &x, 0) != 0) {
        PyBuffer_Release(&y.view);
        return NULL;
    }
    if (x.n != y.n) {
        PyBuffer_Release(&y.view);
        PyBuffer_Release(&x.view);
        PyErr_SetString(PyExc_ValueError, "x and y differ in length");
        return NULL;
    }
    double s[9] = {0.0};
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < x.n; i++) {
        double yc[3], xc[3];
        for (int a = 0; a < 3; a++) {
            yc[a] = AT(y, i, a) - my[a];
            xc[a] = AT(x, i, a) - mx[a];
        }
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) s[3 * a + b] += yc[a] * xc[b];
    }
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&y.view);
    PyBuffer_Release(&x.view);
    return Py_BuildValue("(ddddddddd)", s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8]);
}

/* out_i = |R (c p_i) + t - q_i|: align_positions' arithmetic ((r0 x + r1 y) + r2 z) + t, then the
   norm as numpy's along a row of three, sqrt((d0^2 + d1^2) + d2^2). */
static PyObject *aligned_distances(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *po, *qo;
    Py_buffer out;
    double r[9], t[3], c;
    if (!PyArg_ParseTuple(args, "OOw*(ddddddddd)(ddd)d", &po, &qo, &out, &r[0], &r[1], &r[2], &r[3], &r[4], &r[5],
                          &r[6], &r[7], &r[8], &t[0], &t[1], &t[2], &c))
        return NULL;
    Points p, q;
    if (get_points(po, &p, 0) != 0) {
        PyBuffer_Release(&out);
        return NULL;
    }
    if (get_points(qo, &q, 0) != 0) {
        PyBuffer_Release(&p.view);
        PyBuffer_Release(&out);
        return NULL;
    }
    if (p.n != q.n || out.len != p.n * (Py_ssize_t)sizeof(double)) {
        PyBuffer_Release(&p.view);
        PyBuffer_Release(&q.view);
        PyBuffer_Release(&out);
        PyErr_SetString(PyExc_ValueError, "p, q and out differ in length");
        return NULL;
    }
    double *o = out.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < p.n; i++) {
        double x = c * AT(p, i, 0), y = c * AT(p, i, 1), z = c * AT(p, i, 2), sq = 0.0;
        for (int a = 0; a < 3; a++) {
            double d = (r[3 * a] * x + r[3 * a + 1] * y + r[3 * a + 2] * z + t[a]) - AT(q, i, a);
            sq = a == 0 ? d * d : sq + d * d;
        }
        o[i] = sqrt(sq);
    }
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&p.view);
    PyBuffer_Release(&q.view);
    PyBuffer_Release(&out);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"column_sums", column_sums, METH_O, "column_sums(a) -> (s0, s1, s2): sequential column sums of (n, 3) float64."},
    {"centred_outer_sum", centred_outer_sum, METH_VARARGS,
     "centred_outer_sum(y, my, x, mx) -> 9 floats: sum_i (y_i - my)(x_i - mx)^T row-major, sequential."},
    {"aligned_distances", aligned_distances, METH_VARARGS,
     "aligned_distances(p, q, out, r9, t3, c): out_i = |R (c p_i) + t - q_i| (align_positions, then the norm)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_kernels", NULL, -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&module); }
