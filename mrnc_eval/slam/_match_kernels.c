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

/* ---- the map's k-d tree and the 5 nearest neighbours ---- */

/* The edge or plane map as a k-d tree: a copy of its points reordered so that each node's points
   are one range; median splits on the widest axis; leaves of at most LEAF points. Built once per
   local map, queried ~15,000 times a sweep: it replaced pykdtree there (0.40 against 0.58 us a
   5-NN query on forest30's maps, the same neighbours in the same order). Held by a capsule, so
   Python can neither change nor free it under a search. */
#define LEAF 16
#define TREE_CAPSULE "mrnc_eval.slam._match_kernels.tree"

typedef struct {
    double cut;     /* split value: left points <= cut <= right points */
    int32_t dim;    /* split axis; -1: a leaf */
    int32_t lo, hi; /* the node's points */
    int32_t left, right;
} Node;

typedef struct {
    Py_ssize_t n;
    double *points; /* (n, 3), node order */
    Node *nodes;
    int32_t n_nodes;
} Tree;

static void swap_points(double *p, Py_ssize_t a, Py_ssize_t b) {
    for (int d = 0; d < 3; d++) {
        double t = p[3 * a + d];
        p[3 * a + d] = p[3 * b + d];
        p[3 * b + d] = t;
    }
}

/* Reorder [lo, hi) so that point k has its final rank along dim (three-way partitions: runs of equal
   values take one pass, not one each). */
static void select_rank(double *p, Py_ssize_t lo, Py_ssize_t hi, Py_ssize_t k, int dim) {
    while (hi - lo > 1) {
        double pivot = p[3 * (lo + (hi - lo) / 2) + dim];
        Py_ssize_t lt = lo, i = lo, gt = hi; /* [lo, lt) < pivot, [lt, i) == pivot, [gt, hi) > pivot */
        while (i < gt) {
            double v = p[3 * i + dim];
            if (v < pivot) swap_points(p, lt++, i++);
            else if (v > pivot) swap_points(p, i, --gt);
            else i++;
        }
        if (k < lt) hi = lt;
        else if (k >= gt) lo = gt;
        else return;
    }
}

static int32_t build_node(Tree *t, Py_ssize_t lo, Py_ssize_t hi) {
    int32_t me = t->n_nodes++;
    Node node = {.cut = 0.0, .dim = -1, .lo = (int32_t)lo, .hi = (int32_t)hi, .left = -1, .right = -1};
    t->nodes[me] = node;
    if (hi - lo <= LEAF) return me;
    const double *p = t->points;
    double low[3], high[3];
    for (int d = 0; d < 3; d++) low[d] = high[d] = p[3 * lo + d];
    for (Py_ssize_t i = lo + 1; i < hi; i++)
        for (int d = 0; d < 3; d++) {
            low[d] = p[3 * i + d] < low[d] ? p[3 * i + d] : low[d];
            high[d] = p[3 * i + d] > high[d] ? p[3 * i + d] : high[d];
        }
    int dim = 0;
    for (int d = 1; d < 3; d++)
        if (high[d] - low[d] > high[dim] - low[dim]) dim = d;
    if (!(high[dim] > low[dim])) return me; /* all points equal: one leaf */
    Py_ssize_t mid = lo + (hi - lo) / 2;
    select_rank(t->points, lo, hi, mid, dim);
    t->nodes[me].dim = dim;
    t->nodes[me].cut = p[3 * mid + dim];
    int32_t left = build_node(t, lo, mid);
    t->nodes[me].left = left;
    t->nodes[me].right = build_node(t, mid, hi);
    return me;
}

static void free_tree(Tree *t) {
    if (t == NULL) return;
    PyMem_RawFree(t->points);
    PyMem_RawFree(t->nodes);
    PyMem_RawFree(t);
}

static void tree_capsule_destructor(PyObject *capsule) {
    free_tree(PyCapsule_GetPointer(capsule, TREE_CAPSULE));
}

static PyObject *build_tree(PyObject *self, PyObject *arg) {
    (void)self;
    Held h = {.n = 0};
    if (hold(&h, arg, "points", F64, 2, 3, 0)) return NULL;
    Py_ssize_t n = ROWS(h, 0);
    if (n > INT32_MAX / 2) return fail(&h, PyExc_ValueError, "points: too many for the tree");
    Tree *t = PyMem_RawCalloc(1, sizeof(Tree));
    if (t != NULL) {
        t->n = n;
        t->points = PyMem_RawMalloc((size_t)(n > 0 ? n : 1) * 3 * sizeof(double));
        t->nodes = PyMem_RawMalloc((size_t)(2 * n + 1) * sizeof(Node)); /* leaves hold >= 1 point */
    }
    if (t == NULL || t->points == NULL || t->nodes == NULL) {
        free_tree(t);
        release(&h);
        return PyErr_NoMemory();
    }
    memcpy(t->points, h.v[0].buf, (size_t)n * 3 * sizeof(double));
    release(&h);
    Py_BEGIN_ALLOW_THREADS
    if (n > 0) build_node(t, 0, n);
    Py_END_ALLOW_THREADS
    PyObject *capsule = PyCapsule_New(t, TREE_CAPSULE, tree_capsule_destructor);
    if (capsule == NULL) free_tree(t);
    return capsule;
}

/* One feature's search: the 5 nearest tree points with squared distance below the bound, nearest
   first (a point ties behind the points found before it at the same distance). */
typedef struct {
    const Tree *tree;
    double q[3];
    double best[5];  /* squared distances, ascending; the bound where none yet */
    int32_t idx[5];  /* tree point indices; -1 where none */
} Search;

static void search_leaf(Search *s, const Node *node) {
    const double *p = s->tree->points;
    for (int32_t i = node->lo; i < node->hi; i++) {
        double d0 = s->q[0] - p[3 * i], d1 = s->q[1] - p[3 * i + 1], d2 = s->q[2] - p[3 * i + 2];
        double dd = d0 * d0 + d1 * d1 + d2 * d2;
        if (!(dd < s->best[4])) continue;
        int k = 4;
        for (; k > 0 && s->best[k - 1] > dd; k--) {
            s->best[k] = s->best[k - 1];
            s->idx[k] = s->idx[k - 1];
        }
        s->best[k] = dd;
        s->idx[k] = i;
    }
}

/* The subtree at node, whose box is at least min_sq from q (off: q's offset from the box per axis). */
static void search_node(Search *s, int32_t at, double min_sq, double *off) {
    const Node *node = &s->tree->nodes[at];
    if (node->dim < 0) {
        search_leaf(s, node);
        return;
    }
    int dim = node->dim;
    double diff = s->q[dim] - node->cut;
    search_node(s, diff < 0 ? node->left : node->right, min_sq, off);
    double old = off[dim], far_sq = min_sq - old * old + diff * diff;
    if (far_sq < s->best[4]) {
        off[dim] = diff;
        search_node(s, diff < 0 ? node->right : node->left, far_sq, off);
        off[dim] = old;
    }
}

/* The 5 nearest neighbours of q: 1 when all 5 are nearer than max_dist (m), as sqrt(d^2) < max_dist. */
static int nearest5(Search *s, const double *q, double max_dist) {
    double bound = max_dist * max_dist * (1.0 + 1e-9); /* above every d^2 whose root is < max_dist */
    s->q[0] = q[0];
    s->q[1] = q[1];
    s->q[2] = q[2];
    for (int k = 0; k < 5; k++) {
        s->best[k] = bound;
        s->idx[k] = -1;
    }
    double off[3] = {0.0, 0.0, 0.0};
    if (s->tree->n > 0) search_node(s, 0, 0.0, off);
    return s->idx[4] >= 0 && sqrt(s->best[4]) < max_dist;
}

/* neighbours(tree, q, max_dist, points, dist): each feature's 5 nearest map points (n, 15) and their
   distances (n, 5), nearest first; NaN and inf past the last one within max_dist (the search the
   fits run, for tests). */
static PyObject *neighbours(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *o[4];
    double max_dist;
    if (!PyArg_ParseTuple(args, "OOdOO", &o[0], &o[1], &max_dist, &o[2], &o[3])) return NULL;
    const Tree *tree = PyCapsule_GetPointer(o[0], TREE_CAPSULE);
    Held h = {.n = 0};
    if (tree == NULL || hold(&h, o[1], "q", F64, 2, 3, 0) || hold(&h, o[2], "points", F64, 2, 15, 1) ||
        hold(&h, o[3], "dist", F64, 2, 5, 1)) {
        release(&h);
        return NULL;
    }
    Py_ssize_t n = ROWS(h, 0);
    if (ROWS(h, 1) != n || ROWS(h, 2) != n) return fail(&h, PyExc_ValueError, "points and dist must have q's rows");
    const double *q = DATA(h, 0, double);
    double *pts = DATA(h, 1, double), *dist = DATA(h, 2, double);
    Py_BEGIN_ALLOW_THREADS
    Search s = {.tree = tree};
    for (Py_ssize_t i = 0; i < n; i++) {
        nearest5(&s, q + 3 * i, max_dist);
        for (int k = 0; k < 5; k++) {
            int found = s.idx[k] >= 0;
            dist[5 * i + k] = found ? sqrt(s.best[k]) : INFINITY;
            for (int d = 0; d < 3; d++) pts[15 * i + 3 * k + d] = found ? tree->points[3 * s.idx[k] + d] : NAN;
        }
    }
    Py_END_ALLOW_THREADS
    release(&h);
    Py_RETURN_NONE;
}

/* ---- plane fits ---- */

/* Smaller eigenvalue (m^2) of the 2x2 covariance of the 5 points nb projected on the plane
   with unit normal n. */
static double in_plane_spread(const double *const *nb, double n0, double n1, double n2) {
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
        const double *p = nb[k];
        c0 += p[0] / 5.0;
        c1 += p[1] / 5.0;
        c2 += p[2] / 5.0;
    }
    double a = 0.0, b = 0.0, d = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = nb[k];
        double x0 = p[0] - c0, x1 = p[1] - c1, x2 = p[2] - c2;
        double pu = x0 * u0 + x1 * u1 + x2 * u2, pv = x0 * v0 + x1 * v1 + x2 * v2;
        a += pu * pu / 5.0;
        b += pu * pv / 5.0;
        d += pv * pv / 5.0;
    }
    double h = a - d;
    return 0.5 * (a + d) - sqrt(0.25 * (h * h) + b * b);
}

/* The plane [n, d] (n.x + d = 0, |n| = 1) of one feature's 5 neighbours nb, or 0 when
   none: LIO-SAM's least squares A x = -1 with a 1e-9 ridge, rejected when a neighbour is more than
   max_offset off or the in-plane spread is below min_spread^2. */
static int fit_plane(const double *const *nb, double max_offset, double min_spread, double *out) {
    double a00 = 1e-9, a11 = 1e-9, a22 = 1e-9, a01 = 0.0, a02 = 0.0, a12 = 0.0, b0 = 0.0, b1 = 0.0, b2 = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = nb[k];
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
        const double *p = nb[k];
        if (fabs(n0 * p[0] + n1 * p[1] + n2 * p[2] + d) > max_offset) return 0;
    }
    if (!(in_plane_spread(nb, n0, n1, n2) >= min_spread * min_spread)) return 0;
    out[0] = n0;
    out[1] = n1;
    out[2] = n2;
    out[3] = d;
    return 1;
}

/* The arguments of fit_planes and fit_lines: the map's tree, n features' map points q (n, 3), the
   search bound max_dist (m: a feature whose 5th neighbour is not nearer has no fit), the fits
   (k, width) and `rows`, None (n == k: feature i's fit is row i) or (n,) int64 (feature i's fit
   is row rows[i], each in [0, k)). */
typedef struct {
    Held h;
    const Tree *tree;
    const double *q;
    const int64_t *rows; /* NULL: the identity */
    double *fits, max_dist;
    Py_ssize_t n, width, k; /* k: rows of fits */
} FitArgs;

static int rows_outside(const int64_t *rows, Py_ssize_t n, Py_ssize_t k) {
    for (Py_ssize_t i = 0; i < n; i++)
        if (rows[i] < 0 || rows[i] >= k) return 1;
    return 0;
}

static int hold_fit_args(FitArgs *a, PyObject *const *o, Py_ssize_t width) {
    Held *h = &a->h;
    a->tree = PyCapsule_GetPointer(o[0], TREE_CAPSULE); /* ValueError when not build_tree's */
    if (a->tree == NULL || hold(h, o[1], "q", F64, 2, 3, 0) || hold(h, o[2], "fits", F64, 2, width, 1) ||
        (o[3] != Py_None && hold(h, o[3], "rows", I64, 1, 0, 0)))
        return -1;
    a->n = ROWS(*h, 0);
    a->width = width;
    a->q = DATA(*h, 0, double);
    a->fits = DATA(*h, 1, double);
    a->rows = o[3] != Py_None ? DATA(*h, 2, int64_t) : NULL;
    Py_ssize_t k = a->k = ROWS(*h, 1);
    if ((a->rows != NULL ? ROWS(*h, 2) : k) != a->n) {
        fail(h, PyExc_ValueError, "rows (or fits when rows is None) must have q's length");
        return -1;
    }
    if (a->rows != NULL && rows_outside(a->rows, a->n, k)) {
        fail(h, PyExc_ValueError, "rows: an index outside the fits");
        return -1;
    }
    return 0;
}

/* Feature i's search, and the row of the fits its fit goes to; 0 when it has no 5 neighbours
   within max_dist (the row then NaN). */
static void no_fit(double *row, Py_ssize_t width) {
    for (Py_ssize_t k = 0; k < width; k++) row[k] = NAN;
}

static double *search_feature(const FitArgs *a, Py_ssize_t i, Search *s, const double **nb) {
    /* rows was checked with the GIL held; read once and checked again here, without it, so an array
       changed by another thread in between cannot send a write outside the fits (the feature is skipped) */
    int64_t r = a->rows != NULL ? a->rows[i] : (int64_t)i;
    if (r < 0 || r >= a->k) return NULL;
    double *row = a->fits + a->width * r;
    if (!nearest5(s, a->q + 3 * i, a->max_dist)) {
        no_fit(row, a->width);
        return NULL;
    }
    for (int k = 0; k < 5; k++) nb[k] = a->tree->points + 3 * (Py_ssize_t)s->idx[k];
    return row;
}

static PyObject *fit_planes(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *o[4];
    FitArgs a = {.h = {.n = 0}};
    double max_offset, min_spread;
    if (!PyArg_ParseTuple(args, "OOdddOO", &o[0], &o[1], &a.max_dist, &max_offset, &min_spread, &o[2], &o[3]))
        return NULL;
    if (hold_fit_args(&a, o, 4) != 0) {
        release(&a.h);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    Search s = {.tree = a.tree};
    const double *nb[5];
    for (Py_ssize_t i = 0; i < a.n; i++) {
        double *row = search_feature(&a, i, &s, nb);
        if (row != NULL && !fit_plane(nb, max_offset, min_spread, row)) no_fit(row, 4);
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
static int fit_line(const double *const *nb, double *out) {
    double c0 = 0.0, c1 = 0.0, c2 = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = nb[k];
        c0 += p[0] / 5.0;
        c1 += p[1] / 5.0;
        c2 += p[2] / 5.0;
    }
    double a00 = 0.0, a01 = 0.0, a02 = 0.0, a11 = 0.0, a12 = 0.0, a22 = 0.0;
    for (int k = 0; k < 5; k++) {
        const double *p = nb[k];
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
    PyObject *o[4];
    FitArgs a = {.h = {.n = 0}};
    if (!PyArg_ParseTuple(args, "OOdOO", &o[0], &o[1], &a.max_dist, &o[2], &o[3])) return NULL;
    if (hold_fit_args(&a, o, 6) != 0) {
        release(&a.h);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    Search s = {.tree = a.tree};
    const double *nb[5];
    for (Py_ssize_t i = 0; i < a.n; i++) {
        double *row = search_feature(&a, i, &s, nb);
        if (row != NULL && !fit_line(nb, row)) no_fit(row, 6);
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
    {"build_tree", build_tree, METH_O, "build_tree(points) -> tree: the k-d tree of an (n, 3) float64 map."},
    {"neighbours", neighbours, METH_VARARGS,
     "neighbours(tree, q, max_dist, points, dist): the 5 nearest map points (n, 15) and distances (n, 5) of "
     "each q[i] within max_dist, nearest first; NaN / inf past the last."},
    {"fit_planes", fit_planes, METH_VARARGS,
     "fit_planes(tree, q, max_dist, max_offset, min_spread, planes, rows): the plane [n, d] of the 5 map "
     "neighbours of each feature q[i] into planes[rows[i]] (rows None: planes[i]), NaN where none."},
    {"fit_lines", fit_lines, METH_VARARGS,
     "fit_lines(tree, q, max_dist, lines, rows): the line [centroid, unit direction] of the 5 map neighbours "
     "of each feature q[i] into lines[rows[i]] (rows None: lines[i]), NaN where none."},
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
