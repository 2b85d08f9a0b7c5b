/* PointCloud2 points -> the Sweep's arrays in one pass: the fast path of io/pointcloud.py.

   For little-endian clouds whose x, y, z are float32 (io/pointcloud.py decides, and checks the
   sizes first). A point is kept when |x| + |y| + |z| (float32, added left to right, as the numpy
   path does) is finite and above 0; each kept point's x, y, z and the asked-for fields are written
   at the next row of the outputs, with the casts numpy's astype makes (C conversions, float32
   arithmetic), so the arrays equal the numpy path's bit for bit. The GIL is released meanwhile. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

enum { FLOAT32 = 0, UINT16 = 1, NS_TO_S = 2, ROW = 3, COLUMN = 4, N_KINDS = 5 };
#define MAX_COLUMNS 8

typedef struct {
    int kind, datatype;
    Py_ssize_t offset;
    Py_buffer out;
} Column;

static const int SIZES[9] = {0, 1, 1, 2, 2, 4, 4, 4, 8}; /* sensor_msgs/PointField datatypes 1-8 */

static float as_float(const unsigned char *p, int datatype) {
    switch (datatype) {
    case 1: { int8_t v; memcpy(&v, p, 1); return (float)v; }
    case 2: { uint8_t v; memcpy(&v, p, 1); return (float)v; }
    case 3: { int16_t v; memcpy(&v, p, 2); return (float)v; }
    case 4: { uint16_t v; memcpy(&v, p, 2); return (float)v; }
    case 5: { int32_t v; memcpy(&v, p, 4); return (float)v; }
    case 6: { uint32_t v; memcpy(&v, p, 4); return (float)v; }
    case 7: { float v; memcpy(&v, p, 4); return v; }
    default: { double v; memcpy(&v, p, 8); return (float)v; }
    }
}

static uint16_t as_u16(const unsigned char *p, int datatype) {
    if (datatype == 2) return p[0];
    uint16_t v;
    memcpy(&v, p, 2);
    return v;
}

static void write_column(const Column *c, const unsigned char *point, Py_ssize_t row, Py_ssize_t col,
                         Py_ssize_t k) {
    const unsigned char *p = point + c->offset;
    switch (c->kind) {
    case FLOAT32: ((float *)c->out.buf)[k] = as_float(p, c->datatype); break;
    case UINT16: ((uint16_t *)c->out.buf)[k] = as_u16(p, c->datatype); break;
    case NS_TO_S: ((float *)c->out.buf)[k] = as_float(p, c->datatype) * (float)1e-9; break;
    case ROW: ((uint16_t *)c->out.buf)[k] = (uint16_t)row; break;
    default: ((uint32_t *)c->out.buf)[k] = (uint32_t)col; break;
    }
}

static Py_ssize_t gather_points(const unsigned char *data, const Py_ssize_t shape[4], const Py_ssize_t xyz[3],
                                float *points, const Column *cols, int ncols) {
    Py_ssize_t k = 0;
    for (Py_ssize_t row = 0; row < shape[0]; row++) {
        const unsigned char *line = data + row * shape[3];
        for (Py_ssize_t col = 0; col < shape[1]; col++) {
            const unsigned char *point = line + col * shape[2];
            float x, y, z;
            memcpy(&x, point + xyz[0], 4);
            memcpy(&y, point + xyz[1], 4);
            memcpy(&z, point + xyz[2], 4);
            float norm1 = fabsf(x) + fabsf(y);
            norm1 = norm1 + fabsf(z);
            if (!(isfinite(norm1) && norm1 > 0.0f)) continue; /* no return */
            points[3 * k] = x;
            points[3 * k + 1] = y;
            points[3 * k + 2] = z;
            for (int j = 0; j < ncols; j++) write_column(&cols[j], point, row, col, k);
            k++;
        }
    }
    return k;
}

static const Py_ssize_t ITEM[N_KINDS] = {4, 2, 4, 2, 4}; /* output item size of each kind */

/* One (kind, offset, datatype, out) tuple: -1 with an exception set when it does not fit. */
static int parse_column(PyObject *item, Column *c, Py_ssize_t n, Py_ssize_t step) {
    if (!PyArg_ParseTuple(item, "iniw*", &c->kind, &c->offset, &c->datatype, &c->out)) return -1;
    int sized = c->kind == ROW || c->kind == COLUMN ||
                (c->datatype >= 1 && c->datatype <= 8 && c->offset >= 0 && c->offset <= step - SIZES[c->datatype]);
    if (c->kind < 0 || c->kind >= N_KINDS || !sized || c->out.len < n * ITEM[c->kind] ||
        (c->kind == UINT16 && c->datatype != 2 && c->datatype != 4)) {
        PyBuffer_Release(&c->out);
        PyErr_SetString(PyExc_ValueError, "gather: a column does not fit the cloud or its output");
        return -1;
    }
    return 0;
}

static PyObject *gather(PyObject *self, PyObject *args) {
    Py_buffer data, points;
    Py_ssize_t shape[4], xyz[3];
    PyObject *columns;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*(nnnn)(nnn)w*O!", &data, &shape[0], &shape[1], &shape[2], &shape[3], &xyz[0],
                          &xyz[1], &xyz[2], &points, &PyTuple_Type, &columns))
        return NULL;
    Column cols[MAX_COLUMNS];
    int ncols = 0, ok = 1;
    /* every product in Py_ssize_t without overflow (the sizes are a caller's, not to be trusted) */
    Py_ssize_t n = 0, row_bytes = 0, span = 0, point_bytes = 0;
    int overflow = shape[0] < 0 || shape[1] < 0 || shape[2] <= 0 ||
                   __builtin_mul_overflow(shape[0], shape[1], &n) ||
                   __builtin_mul_overflow(shape[1], shape[2], &row_bytes) ||
                   __builtin_mul_overflow(shape[0] > 0 ? shape[0] - 1 : 0, shape[3], &span) ||
                   __builtin_add_overflow(span, row_bytes, &span) || __builtin_mul_overflow(n, 12, &point_bytes);
    if (overflow || shape[3] < row_bytes || (n > 0 && data.len < span) || points.len < point_bytes ||
        PyTuple_GET_SIZE(columns) > MAX_COLUMNS) {
        PyErr_SetString(PyExc_ValueError, "gather: the cloud's sizes do not add up");
        ok = 0;
    }
    for (int j = 0; j < 3 && ok; j++) ok = xyz[j] >= 0 && xyz[j] + 4 <= shape[2];
    if (ok != 1 && !PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "gather: x/y/z beyond point_step");
    for (Py_ssize_t j = 0; ok && j < PyTuple_GET_SIZE(columns); j++) {
        ok = parse_column(PyTuple_GET_ITEM(columns, j), &cols[ncols], n, shape[2]) == 0;
        ncols += ok;
    }
    Py_ssize_t kept = -1;
    if (ok) {
        Py_BEGIN_ALLOW_THREADS
        kept = gather_points((const unsigned char *)data.buf, shape, xyz, (float *)points.buf, cols, ncols);
        Py_END_ALLOW_THREADS
    }
    for (int j = 0; j < ncols; j++) PyBuffer_Release(&cols[j].out);
    PyBuffer_Release(&data);
    PyBuffer_Release(&points);
    return ok ? PyLong_FromSsize_t(kept) : NULL;
}

static PyMethodDef methods[] = {
    {"gather", gather, METH_VARARGS,
     "gather(data, (height, width, point_step, row_step), (x_off, y_off, z_off), points, columns) -> kept.\n"
     "points: float32 (n, 3); columns: tuple of (kind, offset, datatype, out); kinds 0 float32 cast,\n"
     "1 uint16 (u8/u16 fields), 2 float32 cast times float32(1e-9), 3 row index (uint16), 4 column\n"
     "index (uint32). The first `kept` rows of each output are written."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_cloud", NULL, -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__cloud(void) { return PyModule_Create(&module); }
