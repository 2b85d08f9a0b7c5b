/* Scan-to-map matching's per-correspondence loops (slam/scan_to_map.py): the plane and line fits of
   each feature's 5 map neighbours, the Jacobian and residual rows, the re-query test and the ground
   rows' column zeroing. Compiled ahead of time so a SLAM run loads no JIT; the GIL is released in
   every loop (the reader thread decodes beside the matching).

   Each operation is the one of the numba code these loops replaced, in the same order: sums strictly
   left to right, x ** 2 as x * x, sqrt/acos/cos from libm, no FMA contraction (-ffp-contract=off and
   the pragma below), so each IEEE operation rounds on its own and the poses keep their bits.

   Arguments are C-contiguous numpy arrays, checked here: float64 ("d") or int64 ("l"/"q");
   a wrong dtype raises TypeError, a wrong shape, a non-contiguous array or an index outside the map
   ValueError, so no loop can read or write outside its arrays. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("fp-contract=off")
#endif
#if defined(__clang__)
#pragma clang fp contract(off)
#endif

#define F64 'd'
#define I64 'q'

/* The buffer's item code without a native byte-order prefix; NULL for foreign byte order. */
static const char *item_code(const char *format) {
    if (format == NULL) return "B";
    if (format[0] == '@' || format[0] == '=') return format + 1;
#if PY_LITTLE_ENDIAN
    if (format[0] == '<') return format + 1;
#else
    if (format[0] == '>') return format + 1;
#endif
    if (format[0] == '<' || format[0] == '>' || format[0] == '!') return NULL;
    return format;
}

static int is_kind(const Py_buffer *v, char kind) {
    const char *code = item_code(v->format);
    if (code == NULL || code[0] == '\0' || code[1] != '\0') return 0;
    switch (kind) {
    case F64: return code[0] == 'd' && v->itemsize == 8;
    case I64: return (code[0] == 'q' || code[0] == 'l') && v->itemsize == 8;
    default: return 0;
    }
}

static const char *kind_name(char kind) {
    return kind == F64 ? "float64" : "int64";
}

/* A C-contiguous array of `kind` with `ndim` dimensions; cols > 0 fixes the last dimension of a 2-d
   array. 0, or -1 with an exception set (nothing held). */
static int get_array(PyObject *obj, Py_buffer *v, const char *name, char kind, int ndim, Py_ssize_t cols,
                     int writable) {
    if (PyObject_GetBuffer(obj, v, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0)) != 0)
        return -1;
    if (!is_kind(v, kind)) {
        PyErr_Format(PyExc_TypeError, "%s: expected a %s array", name, kind_name(kind));
        PyBuffer_Release(v);
        return -1;
    }
    if (v->ndim != ndim || (ndim == 2 && cols > 0 && v->shape[1] != cols)) {
        if (ndim == 2 && cols > 0)
            PyErr_Format(PyExc_ValueError, "%s: expected shape (n, %zd)", name, cols);
        else
            PyErr_Format(PyExc_ValueError, "%s: expected %d dimension(s)", name, ndim);
        PyBuffer_Release(v);
        return -1;
    }
    return 0;
}

#define MAX_ARGS 6

/* The buffers of one call, released together. */
typedef struct {
    Py_buffer v[MAX_ARGS];
    int n;
} Held;

static int hold(Held *h, PyObject *obj, const char *name, char kind, int ndim, Py_ssize_t cols, int writable) {
    if (get_array(obj, &h->v[h->n], name, kind, ndim, cols, writable) != 0) return -1;
    h->n++;
    return 0;
}

static void release(Held *h) {
    for (int i = 0; i < h->n; i++) PyBuffer_Release(&h->v[i]);
    h->n = 0;
}

static PyObject *fail(Held *h, PyObject *type, const char *message) {
    release(h);
    PyErr_SetString(type, message);
    return NULL;
}

#define ROWS(h, i) ((h).v[i].shape[0])
#define DATA(h, i, type) ((type *)(h).v[i].buf)

/* ---- plane fits ---- */

/* Smaller eigenvalue (m^2) of the 2x2 covariance of the 5 points cloud[idx] projected on the plane
   with unit normal n. */
static double in_plane_spread(const double *cloud, const int64_t *idx, double n0, double n1, double n2) {
    double u0, u1, u2; /* a vector normal to n */
    if (fabs(n2) < 0.9) {
        u0 = n1;
        u1 = -n0;
        u2 = 0.0;
    } else {
        u0 = 0.0;
        u1 = n2;
        u2 = -n1;
    }
    double un = sqrt(u0 * u0 + u1 * u1 + u2 * u2);
    u0 = u0 / un;
    u1 = u1 / un;
    u2 = u2 / un;
    double v0 = n1 * u2 - n2 * u1, v1 = n2 * u0 - n0 * u2, v2 = n0 * u1 - n1 * u0;
    double c0 = 0.0, c1 = 0.0, c2 = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = cloud + 3 * idx[k];
        c0 += p[0] / 5.0;
        c1 += p[1] / 5.0;
        c2 += p[2] / 5.0;
    }
    double a = 0.0, b = 0.0, d = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = cloud + 3 * idx[k];
        double x0 = p[0] - c0, x1 = p[1] - c1, x2 = p[2] - c2;
        double pu = x0 * u0 + x1 * u1 + x2 * u2, pv = x0 * v0 + x1 * v1 + x2 * v2;
        a += pu * pu / 5.0;
        b += pu * pv / 5.0;
        d += pv * pv / 5.0;
    }
    double h = a - d;
    return 0.5 * (a + d) - sqrt(0.25 * (h * h) + b * b);
}

/* The plane [n, d] (n.x + d = 0, |n| = 1) of one feature's neighbours cloud[idx[0..4]], or 0 when
   none: LIO-SAM's least squares A x = -1 with a 1e-9 ridge, rejected when a neighbour is more than
   max_offset off or the in-plane spread is below min_spread^2. */
static int fit_plane(const double *cloud, const int64_t *idx, double max_offset, double min_spread, double *out) {
    double a00 = 1e-9, a11 = 1e-9, a22 = 1e-9, a01 = 0.0, a02 = 0.0, a12 = 0.0, b0 = 0.0, b1 = 0.0, b2 = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = cloud + 3 * idx[k];
        double x0 = p[0], x1 = p[1], x2 = p[2];
        a00 += x0 * x0;
        a01 += x0 * x1;
        a02 += x0 * x2;
        a11 += x1 * x1;
        a12 += x1 * x2;
        a22 += x2 * x2;
        b0 -= x0;
        b1 -= x1;
        b2 -= x2;
    }
    double c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22, c02 = a01 * a12 - a02 * a11;
    double det = a00 * c00 + a01 * c01 + a02 * c02;
    if (det == 0.0) return 0;
    double c11 = a00 * a22 - a02 * a02, c12 = a01 * a02 - a00 * a12, c22 = a00 * a11 - a01 * a01;
    double x0 = (c00 * b0 + c01 * b1 + c02 * b2) / det;
    double x1 = (c01 * b0 + c11 * b1 + c12 * b2) / det;
    double x2 = (c02 * b0 + c12 * b1 + c22 * b2) / det;
    double nrm = sqrt(x0 * x0 + x1 * x1 + x2 * x2);
    if (nrm < 1e-9) return 0;
    double n0 = x0 / nrm, n1 = x1 / nrm, n2 = x2 / nrm, d = 1.0 / nrm;
    for (int k = 0; k < 5; k++) {
        const double *p = cloud + 3 * idx[k];
        if (fabs(n0 * p[0] + n1 * p[1] + n2 * p[2] + d) > max_offset) return 0;
    }
    if (!(in_plane_spread(cloud, idx, n0, n1, n2) >= min_spread * min_spread)) return 0;
    out[0] = n0;
    out[1] = n1;
    out[2] = n2;
    out[3] = d;
    return 1;
}

/* The arguments of fit_planes and fit_lines: the map cloud (m, 3), the 5 neighbours' indices and
   distances of n features (n, 5), the search bound max_dist (a feature whose 5th neighbour is not
   nearer has no fit), the fits (k, width) and `rows`, None (n == k: feature i's fit is row i) or
   (n,) int64 (feature i's fit is row rows[i]). */
typedef struct {
    Held h;
    const double *cloud, *dist;
    const int64_t *idx, *rows; /* rows NULL: the identity */
    double *fits, max_dist;
    Py_ssize_t n, width;
} FitArgs;

/* Every index a fit will read lies in its array: rows[i] in [0, k); idx[i, :] in [0, m) where the
   feature is matched. 0, or -1 (checked before any fit reads). */
static int check_indices(const FitArgs *a, Py_ssize_t m, Py_ssize_t k) {
    for (Py_ssize_t i = 0; i < a->n; i++) {
        if (a->rows != NULL && (a->rows[i] < 0 || a->rows[i] >= k)) return -1;
        if (!(a->dist[5 * i + 4] < a->max_dist)) continue;
        for (int j = 0; j < 5; j++)
            if (a->idx[5 * i + j] < 0 || a->idx[5 * i + j] >= m) return -1;
    }
    return 0;
}

static int hold_fit_args(FitArgs *a, PyObject *const *o, Py_ssize_t width) {
    Held *h = &a->h;
    if (hold(h, o[0], "cloud", F64, 2, 3, 0) || hold(h, o[1], "idx", I64, 2, 5, 0) ||
        hold(h, o[2], "dist", F64, 2, 5, 0) || hold(h, o[3], "fits", F64, 2, width, 1) ||
        (o[4] != Py_None && hold(h, o[4], "rows", I64, 1, 0, 0)))
        return -1;
    a->n = ROWS(*h, 1);
    a->width = width;
    a->cloud = DATA(*h, 0, double);
    a->idx = DATA(*h, 1, int64_t);
    a->dist = DATA(*h, 2, double);
    a->fits = DATA(*h, 3, double);
    a->rows = o[4] != Py_None ? DATA(*h, 4, int64_t) : NULL;
    Py_ssize_t k = ROWS(*h, 3);
    if (ROWS(*h, 2) != a->n || (a->rows != NULL ? ROWS(*h, 4) : k) != a->n) {
        fail(h, PyExc_ValueError, "idx, dist and rows (or fits when rows is None) differ in length");
        return -1;
    }
    int bad;
    Py_BEGIN_ALLOW_THREADS
    bad = check_indices(a, ROWS(*h, 0), k);
    Py_END_ALLOW_THREADS
    if (bad) {
        fail(h, PyExc_ValueError, "idx or rows: an index outside the cloud or the fits");
        return -1;
    }
    return 0;
}

/* The row of the fits that feature i's fit goes to. */
static double *fit_row(const FitArgs *a, Py_ssize_t i) {
    return a->fits + a->width * (a->rows != NULL ? a->rows[i] : i);
}

static void no_fit(double *row, Py_ssize_t width) {
    for (Py_ssize_t k = 0; k < width; k++) row[k] = NAN;
}

static PyObject *fit_planes(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *o[5];
    FitArgs a = {.h = {.n = 0}};
    double max_offset, min_spread;
    if (!PyArg_ParseTuple(args, "OOOdddOO", &o[0], &o[1], &o[2], &a.max_dist, &max_offset, &min_spread, &o[3], &o[4]))
        return NULL;
    if (hold_fit_args(&a, o, 4) != 0) {
        release(&a.h);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < a.n; i++) {
        double *row = fit_row(&a, i);
        if (!(a.dist[5 * i + 4] < a.max_dist) || !fit_plane(a.cloud, a.idx + 5 * i, max_offset, min_spread, row))
            no_fit(row, 4);
    }
    Py_END_ALLOW_THREADS
    release(&a.h);
    Py_RETURN_NONE;
}

/* ---- line fits ---- */

/* Unit eigenvector u of the largest eigenvalue l1 of the symmetric 3x3 [[a00 a01 a02] [. a11 a12]
   [. . a22]] when l1 > 3 l2 (a line): 1, else 0. Trigonometric roots; the eigenvector is the largest
   cross product of two rows of A - l1 I. */
static int principal_axis(double a00, double a01, double a02, double a11, double a12, double a22, double *u) {
    double q = (a00 + a11 + a22) / 3.0;
    double off = a01 * a01 + a02 * a02 + a12 * a12;
    double e0 = a00 - q, e1 = a11 - q, e2 = a22 - q;
    double p2 = e0 * e0 + e1 * e1 + e2 * e2 + 2.0 * off;
    if (p2 <= 0.0) return 0; /* isotropic (or all points equal) */
    double p = sqrt(p2 / 6.0);
    double b00 = (a00 - q) / p, b11 = (a11 - q) / p, b22 = (a22 - q) / p;
    double b01 = a01 / p, b02 = a02 / p, b12 = a12 / p;
    double half_det =
        0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02));
    double c = half_det > -1.0 ? half_det : -1.0; /* numba's max(-1.0, x) then min(1.0, x): NaN -> -1 */
    c = c < 1.0 ? c : 1.0;
    double phi = acos(c) / 3.0;
    double l1 = q + 2.0 * p * cos(phi);
    double l3 = q + 2.0 * p * cos(phi + 2.0 * M_PI / 3.0);
    double l2 = 3.0 * q - l1 - l3;
    if (!(l1 > 3.0 * l2)) return 0;
    const double r[3][3] = {{a00 - l1, a01, a02}, {a01, a11 - l1, a12}, {a02, a12, a22 - l1}};
    static const int pairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
    double best = -1.0, v0 = 0.0, v1 = 0.0, v2 = 0.0;
    for (int k = 0; k < 3; k++) {
        const double *x = r[pairs[k][0]], *y = r[pairs[k][1]];
        double w0 = x[1] * y[2] - x[2] * y[1], w1 = x[2] * y[0] - x[0] * y[2], w2 = x[0] * y[1] - x[1] * y[0];
        double nn = w0 * w0 + w1 * w1 + w2 * w2;
        if (nn > best) {
            best = nn;
            v0 = w0;
            v1 = w1;
            v2 = w2;
        }
    }
    if (best <= 0.0) return 0;
    double s = 1.0 / sqrt(best);
    u[0] = v0 * s;
    u[1] = v1 * s;
    u[2] = v2 * s;
    return 1;
}

/* The line [centroid, unit direction] of one feature's neighbours, or 0 when none (LIO-SAM: the
   principal axis of their covariance, kept when its eigenvalue exceeds 3x the second). */
static int fit_line(const double *cloud, const int64_t *idx, double *out) {
    double c0 = 0.0, c1 = 0.0, c2 = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = cloud + 3 * idx[k];
        c0 += p[0] / 5.0;
        c1 += p[1] / 5.0;
        c2 += p[2] / 5.0;
    }
    double a00 = 0.0, a01 = 0.0, a02 = 0.0, a11 = 0.0, a12 = 0.0, a22 = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = cloud + 3 * idx[k];
        double d0 = p[0] - c0, d1 = p[1] - c1, d2 = p[2] - c2;
        a00 += d0 * d0 / 5.0;
        a01 += d0 * d1 / 5.0;
        a02 += d0 * d2 / 5.0;
        a11 += d1 * d1 / 5.0;
        a12 += d1 * d2 / 5.0;
        a22 += d2 * d2 / 5.0;
    }
    double u[3];
    if (!principal_axis(a00, a01, a02, a11, a12, a22, u)) return 0;
    out[0] = c0;
    out[1] = c1;
    out[2] = c2;
    out[3] = u[0];
    out[4] = u[1];
    out[5] = u[2];
    return 1;
}

static PyObject *fit_lines(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *o[5];
    FitArgs a = {.h = {.n = 0}};
    if (!PyArg_ParseTuple(args, "OOOdOO", &o[0], &o[1], &o[2], &a.max_dist, &o[3], &o[4])) return NULL;
    if (hold_fit_args(&a, o, 6) != 0) {
        release(&a.h);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < a.n; i++) {
        double *row = fit_row(&a, i);
        if (!(a.dist[5 * i + 4] < a.max_dist) || !fit_line(a.cloud, a.idx + 5 * i, row)) no_fit(row, 6);
    }
    Py_END_ALLOW_THREADS
    release(&a.h);
    Py_RETURN_NONE;
}

/* ---- rows ---- */

/* Row m of a point q with unit direction n and weight s: J = s [(q - o) x n, n] (rotation about the
   point o, map axes; then translation), r = s residual. */
static void write_row(double *J, double *r, const double *q, const double *o, const double *n, double s,
                      double residual) {
    double e0 = q[0] - o[0], e1 = q[1] - o[1], e2 = q[2] - o[2];
    J[0] = s * (e1 * n[2] - e2 * n[1]);
    J[1] = s * (e2 * n[0] - e0 * n[2]);
    J[2] = s * (e0 * n[1] - e1 * n[0]);
    J[3] = s * n[0];
    J[4] = s * n[1];
    J[5] = s * n[2];
    *r = s * residual;
}

/* Point-to-plane rows (LIO-SAM): pd = n.q + d, weight s = 1 - 0.9 |pd| / sqrt(|q|), kept when s > 0.1.
   With min_normal_z > 0, a row whose normal is within acos(min_normal_z) of the z axis (ground:
   |s n_z| > min_normal_z |s n|, the norm summed as numpy's) keeps only its z, roll and pitch columns
   (LeGO-LOAM's split; scan_to_map.py's `_stacked_rows` says why). */
static Py_ssize_t plane_rows_loop(const double *q, Py_ssize_t n, const double *o, const double *planes,
                                  double min_normal_z, double *J, double *r) {
    Py_ssize_t m = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        const double *pl = planes + 4 * i, *qi = q + 3 * i;
        if (pl[0] != pl[0]) continue; /* NaN: no plane */
        double pd = pl[0] * qi[0] + pl[1] * qi[1] + pl[2] * qi[2] + pl[3];
        double s = 1.0 - 0.9 * fabs(pd) / sqrt(sqrt(qi[0] * qi[0] + qi[1] * qi[1] + qi[2] * qi[2]) + 1e-9);
        if (s <= 0.1) continue;
        double *row = J + 6 * m;
        write_row(row, r + m, qi, o, pl, s, pd);
        if (min_normal_z > 0 &&
            fabs(row[5]) > min_normal_z * sqrt(row[3] * row[3] + row[4] * row[4] + row[5] * row[5]))
            row[2] = row[3] = row[4] = 0.0;
        m++;
    }
    return m;
}

/* Point-to-line rows (LIO-SAM): ld = distance to the line, weight s = 1 - 0.9 ld, kept when s > 0.1;
   the row's direction is the unit normal from the line to the point. */
static Py_ssize_t edge_rows_loop(const double *q, Py_ssize_t n, const double *o, const double *lines, double *J,
                                 double *r) {
    Py_ssize_t m = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        const double *ln = lines + 6 * i, *qi = q + 3 * i;
        if (ln[0] != ln[0]) continue; /* NaN: no line */
        double u0 = ln[3], u1 = ln[4], u2 = ln[5];
        double d0 = qi[0] - ln[0], d1 = qi[1] - ln[1], d2 = qi[2] - ln[2];
        double along = d0 * u0 + d1 * u1 + d2 * u2;
        double p0 = d0 - along * u0, p1 = d1 - along * u1, p2 = d2 - along * u2;
        double ld = sqrt(p0 * p0 + p1 * p1 + p2 * p2);
        double s = 1.0 - 0.9 * ld;
        if (s <= 0.1 || ld < 1e-9) continue;
        const double dir[3] = {p0 / ld, p1 / ld, p2 / ld};
        write_row(J + 6 * m, r + m, qi, o, dir, s, ld);
        m++;
    }
    return m;
}

/* rows(q, origin, fits, [min_normal_z,] J, r) for planes (fit width 4) or lines (6): the number of
   rows written. */
static PyObject *rows(PyObject *args, Py_ssize_t width) {
    PyObject *o[5];
    double min_normal_z = 0.0;
    int parsed = width == 4 ? PyArg_ParseTuple(args, "OOOdOO", &o[0], &o[1], &o[2], &min_normal_z, &o[3], &o[4])
                            : PyArg_ParseTuple(args, "OOOOO", &o[0], &o[1], &o[2], &o[3], &o[4]);
    if (!parsed) return NULL;
    Held h = {.n = 0};
    if (hold(&h, o[0], "q", F64, 2, 3, 0) || hold(&h, o[1], "origin", F64, 1, 0, 0) ||
        hold(&h, o[2], "fits", F64, 2, width, 0) || hold(&h, o[3], "J", F64, 2, 6, 1) ||
        hold(&h, o[4], "r", F64, 1, 0, 1)) {
        release(&h);
        return NULL;
    }
    Py_ssize_t n = ROWS(h, 0);
    if (ROWS(h, 1) != 3) return fail(&h, PyExc_ValueError, "origin: expected shape (3,)");
    if (ROWS(h, 2) != n || ROWS(h, 3) < n || ROWS(h, 4) < n)
        return fail(&h, PyExc_ValueError, "fits must have q's rows, J and r at least as many");
    const double *q = DATA(h, 0, double), *origin = DATA(h, 1, double), *fits = DATA(h, 2, double);
    double *J = DATA(h, 3, double), *r = DATA(h, 4, double);
    Py_ssize_t m;
    Py_BEGIN_ALLOW_THREADS
    m = width == 4 ? plane_rows_loop(q, n, origin, fits, min_normal_z, J, r) : edge_rows_loop(q, n, origin, fits, J, r);
    Py_END_ALLOW_THREADS
    release(&h);
    return PyLong_FromSsize_t(m);
}

static PyObject *plane_rows(PyObject *self, PyObject *args) {
    (void)self;
    return rows(args, 4);
}

static PyObject *edge_rows(PyObject *self, PyObject *args) {
    (void)self;
    return rows(args, 6);
}

/* ---- the re-query test ---- */

static PyObject *moved(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *o[3];
    double requery_m;
    if (!PyArg_ParseTuple(args, "OOdO", &o[0], &o[1], &requery_m, &o[2])) return NULL;
    Held h = {.n = 0};
    if (hold(&h, o[0], "q", F64, 2, 3, 0) || hold(&h, o[1], "queried_at", F64, 2, 3, 0) ||
        hold(&h, o[2], "out", I64, 1, 0, 1)) {
        release(&h);
        return NULL;
    }
    Py_ssize_t n = ROWS(h, 0), count = 0;
    if (ROWS(h, 1) != n || ROWS(h, 2) < n)
        return fail(&h, PyExc_ValueError, "queried_at must have q's rows, out at least as many");
    const double *q = DATA(h, 0, double), *at = DATA(h, 1, double);
    int64_t *out = DATA(h, 2, int64_t);
    Py_BEGIN_ALLOW_THREADS
    double lim = requery_m * requery_m;
    for (Py_ssize_t i = 0; i < n; i++) {
        double d0 = q[3 * i] - at[3 * i], d1 = q[3 * i + 1] - at[3 * i + 1], d2 = q[3 * i + 2] - at[3 * i + 2];
        if (d0 * d0 + d1 * d1 + d2 * d2 > lim) out[count++] = i;
    }
    Py_END_ALLOW_THREADS
    release(&h);
    return PyLong_FromSsize_t(count);
}

static PyMethodDef methods[] = {
    {"fit_planes", fit_planes, METH_VARARGS,
     "fit_planes(cloud, idx, dist, max_dist, max_offset, min_spread, planes, rows): the plane [n, d] of each "
     "feature's 5 neighbours cloud[idx[i]] into planes[rows[i]] (rows None: planes[i]), NaN where none."},
    {"fit_lines", fit_lines, METH_VARARGS,
     "fit_lines(cloud, idx, dist, max_dist, lines, rows): the line [centroid, unit direction] of each "
     "feature's 5 neighbours into lines[rows[i]] (rows None: lines[i]), NaN where none."},
    {"plane_rows", plane_rows, METH_VARARGS,
     "plane_rows(q, origin, planes, min_normal_z, J, r) -> m: point-to-plane Jacobian rows and residuals, the "
     "first m written; ground rows vertical-only when min_normal_z > 0."},
    {"edge_rows", edge_rows, METH_VARARGS,
     "edge_rows(q, origin, lines, J, r) -> m: point-to-line Jacobian rows and residuals, the first m written."},
    {"moved", moved, METH_VARARGS,
     "moved(q, queried_at, requery_m, out) -> k: out[:k] = the rows farther than requery_m from queried_at."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_match_kernels", NULL, -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__match_kernels(void) { return PyModule_Create(&module); }
