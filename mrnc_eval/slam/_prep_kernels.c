/* The SLAM's per-sweep preparation loops (range image, deskew, feature labels, ground test, voxel
   centroids, the raw-gyro track), called by slam/range_image.py, deskew.py, features.py and imu.py.
   They replaced numba kernels (issue 30: a `slam` run then loads no numba and no LLVM JIT, ~100 MB
   and ~0.6 s of start-up) and keep their arithmetic: every operation in the same order, plain
   double operations with no FMA contraction (-ffp-contract=off and the pragma below), libm's sqrt,
   floor, hypot, sin and cos as numba called them, and numba's own quicksort for the sector ranking
   (so equal curvatures rank as they did). Every loop runs without the GIL: the range image and the
   labels are computed in the reader thread while the main thread matches (commands/slam.py).

   Arrays come in through the buffer protocol and outputs are allocated by the Python wrappers;
   each argument's dtype (TypeError), shape, length and C-contiguity (ValueError) are checked
   here, and so is every index that addresses another array, so a wrong argument raises instead
   of reading or writing outside an array. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("fp-contract=off")
#endif
#if defined(__clang__)
#pragma clang fp contract(off)
#endif

/* ---------------------------------------------------------------- arrays */

typedef struct {
    Py_buffer view;
    Py_ssize_t n;  /* rows (shape[0]) */
    char kind;     /* 'd' float64, 'f' float32, 'q' int64, '?' bool, 'b' int8 */
} Arr;

static char kind_of(const Py_buffer *v) {
    const char *f = v->format ? v->format : "B";
    if (*f == '@' || *f == '=') f++;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    if (*f == '<') f++;
#endif
    if (f[0] == '\0' || f[1] != '\0') return 0;
    switch (f[0]) {
        case 'd': return v->itemsize == 8 ? 'd' : 0;
        case 'f': return v->itemsize == 4 ? 'f' : 0;
        case 'l': case 'q': return v->itemsize == 8 ? 'q' : 0;
        case '?': return v->itemsize == 1 ? '?' : 0;
        case 'b': return v->itemsize == 1 ? 'b' : 0;
        default: return 0;
    }
}

static const char *kind_name(char k) {
    switch (k) {
        case 'd': return "float64";
        case 'f': return "float32";
        case 'q': return "int64";
        case '?': return "bool";
        case 'b': return "int8";
        default: return "?";
    }
}

/* `obj` as a C-contiguous array of one of `kinds`, `ndim` dimensions, the trailing ones `d1` (and
   `d2`); rows == `rows` unless rows < 0. 0, or -1 with TypeError/ValueError set (nothing held). */
static int get_arr(PyObject *obj, Arr *a, const char *name, const char *kinds, int ndim, Py_ssize_t d1,
                   Py_ssize_t d2, Py_ssize_t rows, int writable) {
    if (PyObject_GetBuffer(obj, &a->view, PyBUF_RECORDS_RO | (writable ? PyBUF_WRITABLE : 0)) != 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "%s: expected a%s numpy array", name, writable ? " writable" : "n");
        a->view.obj = NULL;
        return -1;
    }
    Py_buffer *v = &a->view;
    a->kind = kind_of(v);
    const char *err = NULL;
    PyObject *exc = PyExc_ValueError;
    if (a->kind == 0 || strchr(kinds, a->kind) == NULL) {
        exc = PyExc_TypeError;
        err = "wrong dtype";
    } else if (v->ndim != ndim || (ndim >= 2 && v->shape[1] != d1) || (ndim >= 3 && v->shape[2] != d2)) {
        err = "wrong shape";
    } else if (rows >= 0 && v->shape[0] != rows) {
        err = "wrong length";
    } else if (!PyBuffer_IsContiguous(v, 'C')) {
        err = "not C-contiguous";
    }
    if (err != NULL) {
        char want[64] = "";
        for (const char *k = kinds; *k; k++) {
            strcat(want, k == kinds ? "" : " or ");
            strcat(want, kind_name(*k));
        }
        PyErr_Format(exc, "%s: %s (expected %s, %d-d%s%s)", name, err, want, ndim,
                     ndim >= 2 ? ", trailing shape fixed" : "", rows >= 0 ? ", length matching" : "");
        PyBuffer_Release(v);
        a->view.obj = NULL;
        return -1;
    }
    a->n = ndim > 0 ? v->shape[0] : 1;
    return 0;
}

static void release_all(Arr *a, int count) {
    for (int i = 0; i < count; i++)
        if (a[i].view.obj != NULL) PyBuffer_Release(&a[i].view);
}

#define D(a) ((double *)(a).view.buf)
#define Q(a) ((int64_t *)(a).view.buf)
#define B(a) ((char *)(a).view.buf)

/* element k of a float32 or float64 buffer, as double (exact) */
static inline double real_at(const Arr *a, Py_ssize_t k) {
    return a->kind == 'f' ? (double)((const float *)a->view.buf)[k] : ((const double *)a->view.buf)[k];
}

static PyObject *index_error(const char *what) {
    PyErr_Format(PyExc_ValueError, "%s out of range", what);
    return NULL;
}

/* ---------------------------------------------------------------- range image */

/* range_and_keep(points, keep, rng, min_range, max_range, box): each point's range (m) and
   whether it is kept: finite, within [min_range, max_range], outside box (x_min, y_min, z_min,
   x_max, y_max, z_max) unless box is None. */
static PyObject *range_and_keep(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *po, *ko, *ro, *boxo;
    double lo, hi, box[6] = {0};
    if (!PyArg_ParseTuple(args, "OOOddO", &po, &ko, &ro, &lo, &hi, &boxo)) return NULL;
    int use_box = boxo != Py_None;
    if (use_box && !PyArg_ParseTuple(boxo, "dddddd;box: expected 6 floats", &box[0], &box[1], &box[2], &box[3],
                                     &box[4], &box[5]))
        return NULL;
    Arr a[3] = {0};
    if (get_arr(po, &a[0], "points", "fd", 2, 3, 0, -1, 0) || get_arr(ko, &a[1], "keep", "?", 1, 0, 0, a[0].n, 1) ||
        get_arr(ro, &a[2], "rng", "d", 1, 0, 0, a[0].n, 1)) {
        release_all(a, 3);
        return NULL;
    }
    Py_ssize_t n = a[0].n;
    char *keep = B(a[1]);
    double *rng = D(a[2]);
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < n; i++) {
        double x = real_at(&a[0], 3 * i), y = real_at(&a[0], 3 * i + 1), z = real_at(&a[0], 3 * i + 2);
        double r = sqrt(x * x + y * y + z * z);
        rng[i] = r;
        int k = isfinite(r) && lo <= r && r <= hi;
        if (k && use_box)
            k = !(box[0] <= x && x <= box[3] && box[1] <= y && y <= box[4] && box[2] <= z && z <= box[5]);
        keep[i] = (char)k;
    }
    Py_END_ALLOW_THREADS
    release_all(a, 3);
    Py_RETURN_NONE;
}

/* kept_in_pixel_order(keep, ring, column, width, rate, idx) -> (m, ordered): idx[:m] = the kept
   points on every rate-th ring; ordered: their pixels (ring * width + column) strictly ascend. */
static PyObject *kept_in_pixel_order(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *ko, *ro, *co, *io;
    long long width, rate;
    if (!PyArg_ParseTuple(args, "OOOLLO", &ko, &ro, &co, &width, &rate, &io)) return NULL;
    if (rate <= 0) {
        PyErr_SetString(PyExc_ValueError, "rate must be positive");
        return NULL;
    }
    Arr a[4] = {0};
    if (get_arr(ko, &a[0], "keep", "?", 1, 0, 0, -1, 0) || get_arr(ro, &a[1], "ring", "q", 1, 0, 0, a[0].n, 0) ||
        get_arr(co, &a[2], "column", "q", 1, 0, 0, a[0].n, 0) || get_arr(io, &a[3], "idx", "q", 1, 0, 0, a[0].n, 1)) {
        release_all(a, 4);
        return NULL;
    }
    Py_ssize_t n = a[0].n, m = 0;
    int ordered = 1;
    const char *keep = B(a[0]);
    const int64_t *ring = Q(a[1]), *col = Q(a[2]);
    int64_t *idx = Q(a[3]);
    Py_BEGIN_ALLOW_THREADS
    int64_t last = -1;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (keep[i] && ring[i] % rate == 0) {
            int64_t pixel = (int64_t)((uint64_t)ring[i] * (uint64_t)width + (uint64_t)col[i]);
            if (m > 0 && pixel <= last) ordered = 0;
            last = pixel;
            idx[m++] = i;
        }
    }
    Py_END_ALLOW_THREADS
    release_all(a, 4);
    return Py_BuildValue("(nO)", m, ordered ? Py_True : Py_False);
}

static inline int64_t floor_div(int64_t a, int64_t b) { /* Python's a // b, b > 0 */
    int64_t q = a / b;
    return (a % b != 0 && a < 0) ? q - 1 : q;
}

/* gather(points, ring, column, rng, point_time, idx, rate, out, ring_out, col_out, rng_out, t_out):
   the image's arrays at idx: points and times as float64, ring // rate; point_time and t_out may
   be empty (no per-point time). */
static PyObject *gather(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *o[12];
    long long rate;
    if (!PyArg_ParseTuple(args, "OOOOOOLOOOOO", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &rate, &o[6], &o[7],
                          &o[8], &o[9], &o[10]))
        return NULL;
    if (rate <= 0) {
        PyErr_SetString(PyExc_ValueError, "rate must be positive");
        return NULL;
    }
    Arr a[11] = {0};
    int fail = get_arr(o[0], &a[0], "points", "fd", 2, 3, 0, -1, 0);
    Py_ssize_t n = a[0].n;
    fail = fail || get_arr(o[1], &a[1], "ring", "q", 1, 0, 0, n, 0) || get_arr(o[2], &a[2], "column", "q", 1, 0, 0, n, 0) ||
           get_arr(o[3], &a[3], "rng", "d", 1, 0, 0, n, 0) || get_arr(o[4], &a[4], "point_time", "fd", 1, 0, 0, -1, 0) ||
           get_arr(o[5], &a[5], "idx", "q", 1, 0, 0, -1, 0);
    Py_ssize_t m = fail ? 0 : a[5].n, nt = fail ? 0 : (a[4].n ? m : 0);
    fail = fail || get_arr(o[6], &a[6], "out", "d", 2, 3, 0, m, 1) || get_arr(o[7], &a[7], "ring_out", "q", 1, 0, 0, m, 1) ||
           get_arr(o[8], &a[8], "col_out", "q", 1, 0, 0, m, 1) || get_arr(o[9], &a[9], "rng_out", "d", 1, 0, 0, m, 1) ||
           get_arr(o[10], &a[10], "t_out", "d", 1, 0, 0, nt, 1);
    if (!fail && a[4].n != 0 && a[4].n != n) {
        PyErr_SetString(PyExc_ValueError, "point_time: one per point, or empty");
        fail = 1;
    }
    if (fail) {
        release_all(a, 11);
        return NULL;
    }
    const int64_t *ring = Q(a[1]), *col = Q(a[2]), *idx = Q(a[5]);
    const double *rng = D(a[3]);
    double *out = D(a[6]), *rng_out = D(a[9]), *t_out = D(a[10]);
    int64_t *ring_out = Q(a[7]), *col_out = Q(a[8]);
    int bad = 0;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t j = 0; j < m; j++) {
        int64_t i = idx[j];
        if (i < 0 || i >= n) {
            bad = 1;
            break;
        }
        for (int c = 0; c < 3; c++) out[3 * j + c] = real_at(&a[0], 3 * i + c);
        ring_out[j] = floor_div(ring[i], rate);
        col_out[j] = col[i];
        rng_out[j] = rng[i];
        if (nt) t_out[j] = real_at(&a[4], i);
    }
    Py_END_ALLOW_THREADS
    release_all(a, 11);
    if (bad) return index_error("idx");
    Py_RETURN_NONE;
}

/* ---------------------------------------------------------------- deskew */

/* deskew_apply(points, t, t0, table, velocity, accel, out): out_i = R_k p_i + v t_i + a t_i^2 / 2,
   R_k the table's rotation nearest t_i - t0 (one per ms, clamped to the table). */
static PyObject *deskew_apply(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *po, *to, *tbo, *outo;
    double t0, v[3], acc[3];
    if (!PyArg_ParseTuple(args, "OOdO(ddd)(ddd)O", &po, &to, &t0, &tbo, &v[0], &v[1], &v[2], &acc[0], &acc[1],
                          &acc[2], &outo))
        return NULL;
    Arr a[4] = {0};
    if (get_arr(po, &a[0], "points", "d", 2, 3, 0, -1, 0) || get_arr(to, &a[1], "t", "d", 1, 0, 0, a[0].n, 0) ||
        get_arr(tbo, &a[2], "table", "d", 3, 3, 3, -1, 0) || get_arr(outo, &a[3], "out", "d", 2, 3, 0, a[0].n, 1)) {
        release_all(a, 4);
        return NULL;
    }
    if (a[2].n < 1) {
        release_all(a, 4);
        PyErr_SetString(PyExc_ValueError, "table: at least one rotation");
        return NULL;
    }
    Py_ssize_t n = a[0].n;
    int64_t last = a[2].n - 1;
    const double *p = D(a[0]), *t = D(a[1]), *tb = D(a[2]);
    double *out = D(a[3]);
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t k = (int64_t)floor((t[i] - t0) / 1e-3 + 0.5);
        k = k < 0 ? 0 : k;
        k = k < last ? k : last;
        const double *r = tb + 9 * k;
        for (int c = 0; c < 3; c++)
            out[3 * i + c] = r[3 * c] * p[3 * i] + r[3 * c + 1] * p[3 * i + 1] + r[3 * c + 2] * p[3 * i + 2] +
                             v[c] * t[i] + 0.5 * acc[c] * t[i] * t[i];
    }
    Py_END_ALLOW_THREADS
    release_all(a, 4);
    Py_RETURN_NONE;
}

/* ---------------------------------------------------------------- features */

/* smoothness(rng, xyz, paper, out): LIO-SAM's code, (sum of the 10 neighbour ranges - 10 r_i)^2;
   paper (LOAM): |sum_u (p_i - p_u)| / (10 |p_i|); 0 for the 5 points at either end. */
static PyObject *smoothness(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *ro, *xo, *oo;
    int paper;
    if (!PyArg_ParseTuple(args, "OOpO", &ro, &xo, &paper, &oo)) return NULL;
    Arr a[3] = {0};
    if (get_arr(ro, &a[0], "rng", "d", 1, 0, 0, -1, 0) || get_arr(xo, &a[1], "xyz", "d", 2, 3, 0, a[0].n, 0) ||
        get_arr(oo, &a[2], "out", "d", 1, 0, 0, a[0].n, 1)) {
        release_all(a, 3);
        return NULL;
    }
    Py_ssize_t n = a[0].n;
    const double *rng = D(a[0]), *x = D(a[1]);
    double *curv = D(a[2]);
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < n; i++) curv[i] = 0.0;
    for (Py_ssize_t i = 5; i < n - 5; i++) {
        if (paper) {
            double s = 0.0;
            for (int c = 0; c < 3; c++) {
                double d = 10.0 * x[3 * i + c];
                for (int k = 1; k < 6; k++) d -= x[3 * (i - k) + c] + x[3 * (i + k) + c];
                s += d * d;
            }
            double norm = sqrt(x[3 * i] * x[3 * i] + x[3 * i + 1] * x[3 * i + 1] + x[3 * i + 2] * x[3 * i + 2]);
            curv[i] = norm > 0 ? sqrt(s) / (10.0 * norm) : 0.0;
        } else {
            double d = -10.0 * rng[i];
            for (int k = 1; k < 6; k++) d += rng[i - k] + rng[i + k];
            curv[i] = d * d;
        }
    }
    Py_END_ALLOW_THREADS
    release_all(a, 3);
    Py_RETURN_NONE;
}

/* numba's np.argsort (kind "quicksort", numba/misc/quicksort.py) over doubles, NaN last: the same
   pivots, partitions and insertion sorts, so ties come out in numba's order. r[0:n] = 0..n-1 on entry. */
#define SMALL_QUICKSORT 15
#define MAX_STACK 100

static inline int lt_float(double a, double b) { return a < b || (isnan(b) && !isnan(a)); }

#define SWAP(i, j) do { int64_t tmp_ = r[i]; r[i] = r[j]; r[j] = tmp_; } while (0)

static void insertion_sort(const double *v, int64_t *r, int64_t low, int64_t high) {
    for (int64_t i = low + 1; i <= high; i++) {
        int64_t k = r[i];
        double x = v[k];
        int64_t j = i;
        while (j > low && lt_float(x, v[r[j - 1]])) {
            r[j] = r[j - 1];
            j--;
        }
        r[j] = k;
    }
}

static int64_t partition(const double *v, int64_t *r, int64_t low, int64_t high) {
    int64_t mid = (low + high) >> 1;
    if (lt_float(v[r[mid]], v[r[low]])) SWAP(low, mid);
    if (lt_float(v[r[high]], v[r[mid]])) SWAP(high, mid);
    if (lt_float(v[r[mid]], v[r[low]])) SWAP(low, mid);
    double pivot = v[r[mid]];
    SWAP(high, mid);
    int64_t i = low, j = high - 1;
    for (;;) {
        while (i < high && lt_float(v[r[i]], pivot)) i++;
        while (j >= low && lt_float(pivot, v[r[j]])) j--;
        if (i >= j) break;
        SWAP(i, j);
        i++;
        j--;
    }
    SWAP(i, high);
    return i;
}

/* 0, or -1 when the partition stack would overflow (it cannot: the larger side is pushed) */
static int argsort(const double *v, int64_t *r, int64_t n) {
    for (int64_t i = 0; i < n; i++) r[i] = i;
    if (n < 2) return 0;
    int64_t stack_lo[MAX_STACK], stack_hi[MAX_STACK];
    int top = 1;
    stack_lo[0] = 0;
    stack_hi[0] = n - 1;
    while (top > 0) {
        top--;
        int64_t low = stack_lo[top], high = stack_hi[top];
        while (high - low >= SMALL_QUICKSORT) {
            if (top >= MAX_STACK) return -1;
            int64_t i = partition(v, r, low, high);
            if (high - i > i - low) {
                if (high > i) {
                    stack_lo[top] = i + 1;
                    stack_hi[top] = high;
                    top++;
                }
                high = i - 1;
            } else {
                if (i > low) {
                    stack_lo[top] = low;
                    stack_hi[top] = i - 1;
                    top++;
                }
                low = i + 1;
            }
        }
        insertion_sort(v, r, low, high);
    }
    return 0;
}

static inline int64_t abs64(int64_t x) { return x < 0 ? -x : x; }

/* A selected feature blocks its +/-5 neighbours on the ring, up to a column gap > 10. */
static void mark_neighbours(char *picked, const int64_t *col, int64_t n, int64_t i) {
    picked[i] = 1;
    for (int64_t k = 1; k < 6; k++) {
        if (i + k < n && abs64(col[i + k] - col[i + k - 1]) <= 10)
            picked[i + k] = 1;
        else
            break;
    }
    for (int64_t k = 1; k < 6; k++) {
        if (i - k >= 0 && abs64(col[i - k] - col[i - k + 1]) <= 10)
            picked[i - k] = 1;
        else
            break;
    }
}

/* LIO-SAM's unreliable points: the far side of an occlusion and beams nearly parallel to the surface. */
static void mark_occluded_and_parallel(const double *rng, const int64_t *col, int64_t n, double occ_jump,
                                       double par_ratio, char *picked) {
    for (int64_t i = 5; i < n - 6; i++) {
        if (abs64(col[i + 1] - col[i]) < 10) {
            if (rng[i] - rng[i + 1] > occ_jump) {
                for (int64_t k = i - 5; k < i + 1; k++) picked[k] = 1;
            } else if (rng[i + 1] - rng[i] > occ_jump) {
                for (int64_t k = i + 1; k < i + 7; k++) picked[k] = 1;
            }
        }
    }
    for (int64_t i = 5; i < n - 6; i++)
        if (fabs(rng[i - 1] - rng[i]) > par_ratio * rng[i] && fabs(rng[i + 1] - rng[i]) > par_ratio * rng[i])
            picked[i] = 1;
}

typedef struct {
    const double *curv;
    const int64_t *col;
    int64_t n;
    char *picked;
    int8_t *label;
    int64_t *order; /* scratch, one per point */
    double edge_thr, surf_thr;
    int64_t max_edges;
} Sector;

/* One sector [sp, ep]: the sharpest unpicked points above edge_thr become edges (at most
   max_edges), the flattest below surf_thr planes; each blocks its neighbours; every other
   non-edge point of the sector is planar (-2). */
static int label_sector(const Sector *s, int64_t sp, int64_t ep) {
    int64_t len = ep - sp + 1, *idx = s->order;
    if (argsort(s->curv + sp, idx, len) != 0) return -1;
    int64_t count = 0;
    for (int64_t q = len - 1; q >= 0; q--) {
        int64_t i = idx[q] + sp;
        if (s->picked[i] || s->curv[i] <= s->edge_thr) continue;
        count++;
        if (count > s->max_edges) break;
        s->label[i] = 1;
        mark_neighbours(s->picked, s->col, s->n, i);
    }
    for (int64_t q = 0; q < len; q++) {
        int64_t i = idx[q] + sp;
        if (s->picked[i] || s->curv[i] >= s->surf_thr) continue;
        s->label[i] = -1;
        mark_neighbours(s->picked, s->col, s->n, i);
    }
    for (int64_t i = sp; i <= ep; i++)
        if (s->label[i] == 0) s->label[i] = -2;
    return 0;
}

/* extract(rng, curv, col, ring_start, ring_end, edge_thr, surf_thr, max_edges, sectors, occ_jump,
   par_ratio, label): labels per point, 1 edge, -1 / -2 planar, 0 neither; each ring [start, end)
   split into `sectors` equal sectors. */
static PyObject *extract(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *o[6];
    Sector s = {0};
    long long max_edges, sectors;
    double occ_jump, par_ratio;
    if (!PyArg_ParseTuple(args, "OOOOOddLLddO", &o[0], &o[1], &o[2], &o[3], &o[4], &s.edge_thr, &s.surf_thr,
                          &max_edges, &sectors, &occ_jump, &par_ratio, &o[5]))
        return NULL;
    if (sectors <= 0) {
        PyErr_SetString(PyExc_ValueError, "sectors must be positive");
        return NULL;
    }
    Arr a[6] = {0};
    int fail = get_arr(o[0], &a[0], "rng", "d", 1, 0, 0, -1, 0);
    Py_ssize_t n = a[0].n;
    fail = fail || get_arr(o[1], &a[1], "curv", "d", 1, 0, 0, n, 0) || get_arr(o[2], &a[2], "col", "q", 1, 0, 0, n, 0) ||
           get_arr(o[3], &a[3], "ring_start", "q", 1, 0, 0, -1, 0) ||
           get_arr(o[4], &a[4], "ring_end", "q", 1, 0, 0, a[3].n, 0) || get_arr(o[5], &a[5], "label", "b", 1, 0, 0, n, 1);
    if (fail) {
        release_all(a, 6);
        return NULL;
    }
    const int64_t *starts = Q(a[3]), *ends = Q(a[4]);
    for (Py_ssize_t r = 0; r < a[3].n; r++) {
        if (ends[r] - starts[r] >= 6 * sectors && (starts[r] < 0 || ends[r] > n)) {
            release_all(a, 6);
            return index_error("ring_start/ring_end");
        }
    }
    s.curv = D(a[1]);
    s.col = Q(a[2]);
    s.n = n;
    s.max_edges = max_edges;
    s.label = (int8_t *)a[5].view.buf;
    s.picked = calloc(n > 0 ? n : 1, 1);
    s.order = malloc(sizeof(int64_t) * (n > 0 ? n : 1));
    if (s.picked == NULL || s.order == NULL) {
        free(s.picked);
        free(s.order);
        release_all(a, 6);
        return PyErr_NoMemory();
    }
    int err = 0;
    Py_BEGIN_ALLOW_THREADS
    memset(s.label, 0, n);
    mark_occluded_and_parallel(D(a[0]), s.col, n, occ_jump, par_ratio, s.picked);
    for (Py_ssize_t r = 0; r < a[3].n && !err; r++) {
        int64_t st = starts[r], e = ends[r];
        if (e - st < 6 * sectors) continue;
        for (int64_t j = 0; j < sectors && !err; j++) {
            int64_t sp = (st * (sectors - j) + e * j) / sectors;
            int64_t ep = (st * (sectors - 1 - j) + e * (j + 1)) / sectors - 1;
            if (sp < ep) err = label_sector(&s, sp, ep);
        }
    }
    Py_END_ALLOW_THREADS
    free(s.picked);
    free(s.order);
    release_all(a, 6);
    if (err) {
        PyErr_SetString(PyExc_RuntimeError, "sector sort: partition stack overflow");
        return NULL;
    }
    Py_RETURN_NONE;
}

/* vertical_neighbours(ring, col, rows, width, out): each point's neighbour in the same column on
   the row above and below, -1 where that pixel is empty (the last point of a pixel wins). */
static PyObject *vertical_neighbours(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *ro, *co, *oo;
    long long rows, width;
    if (!PyArg_ParseTuple(args, "OOLLO", &ro, &co, &rows, &width, &oo)) return NULL;
    if (rows < 0 || width < 0 || (width > 0 && rows > PY_SSIZE_T_MAX / 8 / width)) {
        PyErr_SetString(PyExc_ValueError, "rows, width: out of range");
        return NULL;
    }
    Arr a[3] = {0};
    if (get_arr(ro, &a[0], "ring", "q", 1, 0, 0, -1, 0) || get_arr(co, &a[1], "col", "q", 1, 0, 0, a[0].n, 0) ||
        get_arr(oo, &a[2], "out", "q", 2, 2, 0, a[0].n, 1)) {
        release_all(a, 3);
        return NULL;
    }
    Py_ssize_t n = a[0].n;
    int64_t *grid = malloc(sizeof(int64_t) * (size_t)(rows * width > 0 ? rows * width : 1));
    if (grid == NULL) {
        release_all(a, 3);
        return PyErr_NoMemory();
    }
    const int64_t *ring = Q(a[0]), *col = Q(a[1]);
    int64_t *out = Q(a[2]);
    int bad = 0;
    Py_BEGIN_ALLOW_THREADS
    for (int64_t k = 0; k < rows * width; k++) grid[k] = -1;
    for (Py_ssize_t i = 0; i < n && !bad; i++) {
        if (ring[i] < 0 || ring[i] >= rows || col[i] < 0 || col[i] >= width)
            bad = 1;
        else
            grid[ring[i] * width + col[i]] = i;
    }
    for (Py_ssize_t i = 0; i < n && !bad; i++) {
        out[2 * i] = ring[i] > 0 ? grid[(ring[i] - 1) * width + col[i]] : -1;
        out[2 * i + 1] = ring[i] + 1 < rows ? grid[(ring[i] + 1) * width + col[i]] : -1;
    }
    Py_END_ALLOW_THREADS
    free(grid);
    release_all(a, 3);
    if (bad) return index_error("ring/col");
    Py_RETURN_NONE;
}

/* ground_mask's test of one pair, a on the upper ring and b below it */
static inline int flat_pair(const double *p, int64_t a, int64_t b, double tan_max) {
    double d0 = p[3 * b] - p[3 * a], d1 = p[3 * b + 1] - p[3 * a + 1], d2 = p[3 * b + 2] - p[3 * a + 2];
    return fabs(d2) < tan_max * hypot(d0, d1) && p[3 * a + 2] < 0 && p[3 * b + 2] < 0;
}

/* ground_of(points, candidates, vertical, tan_max, out): the ground test at the candidates only:
   ground when the pair with the upper or the lower neighbour is flat. */
static PyObject *ground_of(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *po, *co, *vo, *oo;
    double tan_max;
    if (!PyArg_ParseTuple(args, "OOOdO", &po, &co, &vo, &tan_max, &oo)) return NULL;
    Arr a[4] = {0};
    if (get_arr(po, &a[0], "points", "d", 2, 3, 0, -1, 0) || get_arr(co, &a[1], "candidates", "q", 1, 0, 0, -1, 0) ||
        get_arr(vo, &a[2], "vertical", "q", 2, 2, 0, a[0].n, 0) || get_arr(oo, &a[3], "out", "?", 1, 0, 0, a[1].n, 1)) {
        release_all(a, 4);
        return NULL;
    }
    Py_ssize_t n = a[0].n, m = a[1].n;
    const double *p = D(a[0]);
    const int64_t *cand = Q(a[1]), *vert = Q(a[2]);
    char *out = B(a[3]);
    int bad = 0;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t q = 0; q < m; q++) {
        int64_t i = cand[q];
        if (i < 0 || i >= n || vert[2 * i] >= n || vert[2 * i + 1] >= n) {
            bad = 1;
            break;
        }
        int64_t up = vert[2 * i], down = vert[2 * i + 1];
        out[q] = (char)((up >= 0 && flat_pair(p, up, i, tan_max)) || (down >= 0 && flat_pair(p, i, down, tan_max)));
    }
    Py_END_ALLOW_THREADS
    release_all(a, 4);
    if (bad) return index_error("candidates/vertical");
    Py_RETURN_NONE;
}

/* voxel_centroids(points, leaf) -> bytearray of (m, 3) float64: one centroid per voxel, first-seen
   order; an open-addressing hash of packed voxel keys (21 bits per axis, keys within +/-2^20). */
static PyObject *voxel_centroids(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *po;
    double leaf;
    if (!PyArg_ParseTuple(args, "Od", &po, &leaf)) return NULL;
    if (!(leaf > 0)) {
        PyErr_SetString(PyExc_ValueError, "leaf must be positive");
        return NULL;
    }
    Arr a[1] = {0};
    if (get_arr(po, &a[0], "points", "d", 2, 3, 0, -1, 0)) return NULL;
    Py_ssize_t n = a[0].n;
    if (n == 0) {
        release_all(a, 1);
        return PyByteArray_FromStringAndSize(NULL, 0);
    }
    int64_t cap = 1;
    int bits = 0;
    while (cap < 2 * n) {
        cap *= 2;
        bits++;
    }
    int64_t *table = malloc(sizeof(int64_t) * cap), *counts = calloc(n, sizeof(int64_t));
    uint64_t *keys = malloc(sizeof(uint64_t) * n);
    double *sums = calloc(3 * (size_t)n, sizeof(double));
    if (table == NULL || counts == NULL || keys == NULL || sums == NULL) {
        free(table), free(counts), free(keys), free(sums);
        release_all(a, 1);
        return PyErr_NoMemory();
    }
    const double *p = D(a[0]);
    int64_t m = 0;
    Py_BEGIN_ALLOW_THREADS
    for (int64_t k = 0; k < cap; k++) table[k] = -1;
    const uint64_t mask = (uint64_t)cap - 1, golden = 0x9E3779B97F4A7C15ull;  /* -7046029254386353131 as int64 */
    for (Py_ssize_t i = 0; i < n; i++) {
        /* unsigned arithmetic: the two's-complement wrap of numba's int64 shifts and product */
        uint64_t kx = (uint64_t)(int64_t)floor(p[3 * i] / leaf) + (1u << 20);
        uint64_t ky = (uint64_t)(int64_t)floor(p[3 * i + 1] / leaf) + (1u << 20);
        uint64_t kz = (uint64_t)(int64_t)floor(p[3 * i + 2] / leaf) + (1u << 20);
        uint64_t key = (kx << 42) | (ky << 21) | kz;
        uint64_t h = ((key * golden) >> (64 - bits)) & mask;  /* Fibonacci hash: the top bits */
        int64_t j;
        for (;;) {
            j = table[h];
            if (j < 0) {
                table[h] = m;
                keys[m] = key;
                j = m++;
                break;
            }
            if (keys[j] == key) break;
            h = (h + 1) & mask;
        }
        sums[3 * j] += p[3 * i];
        sums[3 * j + 1] += p[3 * i + 1];
        sums[3 * j + 2] += p[3 * i + 2];
        counts[j] += 1;
    }
    for (int64_t j = 0; j < m; j++)
        for (int c = 0; c < 3; c++) sums[3 * j + c] = sums[3 * j + c] / (double)counts[j];
    free(table), free(counts), free(keys);
    Py_END_ALLOW_THREADS
    PyObject *out = PyByteArray_FromStringAndSize((const char *)sums, (Py_ssize_t)(sizeof(double) * 3 * m));
    free(sums);
    release_all(a, 1);
    return out;
}

/* ---------------------------------------------------------------- IMU */

/* integrate_gyro(gyro, dt, q): quaternions (w, x, y, z) of the raw gyro integration, one per
   sample, the first the identity; q holds zeros on entry. */
static PyObject *integrate_gyro(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *go, *dto, *qo;
    if (!PyArg_ParseTuple(args, "OOO", &go, &dto, &qo)) return NULL;
    Arr a[3] = {0};
    if (get_arr(go, &a[0], "gyro", "d", 2, 3, 0, -1, 0) || get_arr(dto, &a[1], "dt", "d", 1, 0, 0, a[0].n, 0) ||
        get_arr(qo, &a[2], "q", "d", 2, 4, 0, a[0].n, 1)) {
        release_all(a, 3);
        return NULL;
    }
    Py_ssize_t n = a[0].n;
    const double *g = D(a[0]), *dt = D(a[1]);
    double *q = D(a[2]);
    Py_BEGIN_ALLOW_THREADS
    if (n > 0) {
        q[0] = 1.0;
        q[1] = q[2] = q[3] = 0.0;
    }
    for (Py_ssize_t i = 0; i + 1 < n; i++) {
        double wx = g[3 * i] * dt[i], wy = g[3 * i + 1] * dt[i], wz = g[3 * i + 2] * dt[i];
        double ang = sqrt(wx * wx + wy * wy + wz * wz);
        double dw, dx, dy, dz;
        if (ang > 1e-12) {
            double s = sin(0.5 * ang) / ang;
            dw = cos(0.5 * ang), dx = wx * s, dy = wy * s, dz = wz * s;
        } else {
            dw = 1.0, dx = 0.5 * wx, dy = 0.5 * wy, dz = 0.5 * wz;
        }
        const double *c = q + 4 * i;
        double aw = c[0], ax = c[1], ay = c[2], az = c[3];
        double w = aw * dw - ax * dx - ay * dy - az * dz;
        double x = aw * dx + ax * dw + ay * dz - az * dy;
        double y = aw * dy - ax * dz + ay * dw + az * dx;
        double z = aw * dz + ax * dy - ay * dx + az * dw;
        double nrm = sqrt(w * w + x * x + y * y + z * z);
        double *o = q + 4 * (i + 1);
        o[0] = w / nrm, o[1] = x / nrm, o[2] = y / nrm, o[3] = z / nrm;
    }
    Py_END_ALLOW_THREADS
    release_all(a, 3);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"range_and_keep", range_and_keep, METH_VARARGS,
     "range_and_keep(points, keep, rng, min_range, max_range, box): ranges and the kept mask, in place."},
    {"kept_in_pixel_order", kept_in_pixel_order, METH_VARARGS,
     "kept_in_pixel_order(keep, ring, column, width, rate, idx) -> (m, ordered)."},
    {"gather", gather, METH_VARARGS,
     "gather(points, ring, column, rng, point_time, idx, rate, out, ring_out, col_out, rng_out, t_out)."},
    {"deskew_apply", deskew_apply, METH_VARARGS, "deskew_apply(points, t, t0, table, velocity, accel, out)."},
    {"smoothness", smoothness, METH_VARARGS, "smoothness(rng, xyz, paper, out)."},
    {"extract", extract, METH_VARARGS,
     "extract(rng, curv, col, ring_start, ring_end, edge_thr, surf_thr, max_edges, sectors, occ_jump, par_ratio, "
     "label)."},
    {"vertical_neighbours", vertical_neighbours, METH_VARARGS, "vertical_neighbours(ring, col, rows, width, out)."},
    {"ground_of", ground_of, METH_VARARGS, "ground_of(points, candidates, vertical, tan_max, out)."},
    {"voxel_centroids", voxel_centroids, METH_VARARGS, "voxel_centroids(points, leaf) -> bytearray of (m, 3) float64."},
    {"integrate_gyro", integrate_gyro, METH_VARARGS, "integrate_gyro(gyro, dt, q): the raw gyro track, in place."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_prep_kernels", NULL, -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__prep_kernels(void) { return PyModule_Create(&module); }
