/* Plain text tables of numbers -> column-major float64: the fast path of io/number_table.py.

   "Plain" is a strict subset of what the strict (pandas) path reads: an optional UTF-8 BOM, lines
   ending in \n or \r\n, empty lines and ASCII '#' comment lines anywhere, and rows of exactly
   ncols decimal numbers ([+-] digits [. digits] [e|E [+-] digits], at most 64 characters) separated
   by single spaces. On anything else it returns NOT_PLAIN and the caller reads the file with the
   strict path, which names the bad line.

   Numbers round exactly as float() (correctly): integer mantissa / power of ten when both are
   exact doubles (at most 19 digits, mantissa <= 2^53, at most 22 decimals; one IEEE division is
   then correctly rounded), strtod (correctly rounded in glibc) otherwise. Each line is found with
   memchr and its numbers read in one pass over the characters. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define BLOCK_BYTES (1 << 20) /* read size; a longer line is NOT_PLAIN */
#define MAX_TOKEN 64
#define NOT_PLAIN (-1)
#define READ_ERROR (-2)

static const double POW10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int is_digit(char c) { return (unsigned char)(c - '0') < 10; }

/* The number starting at *cursor (before `end`) into *out, *cursor moved past it; 0, or
   NOT_PLAIN when it is not a plain finite decimal of at most MAX_TOKEN characters. One pass over
   the characters: at most 19 digits (leading zeros included) fit a uint64 mantissa exactly; the
   rest (longer numbers, exponents) goes to strtod. */
static inline int parse_number(const char **cursor, const char *end, double *out) {
    const char *s = *cursor, *p = s;
    int negative = 0;
    if (p < end && (*p == '+' || *p == '-')) {
        negative = *p == '-';
        p++;
    }
    uint64_t mantissa = 0; /* wraps past 19 digits: then unused */
    const char *digits_start = p;
    while (p < end && is_digit(*p)) mantissa = mantissa * 10 + (uint64_t)(*p++ - '0');
    ptrdiff_t digits = p - digits_start, decimals = 0;
    if (p < end && *p == '.') {
        const char *fraction = ++p;
        while (p < end && is_digit(*p)) mantissa = mantissa * 10 + (uint64_t)(*p++ - '0');
        decimals = p - fraction;
        digits += decimals;
    }
    if (digits == 0) return NOT_PLAIN;
    int exact = digits <= 19;
    if (p < end && (*p == 'e' || *p == 'E')) {
        exact = 0;
        p++;
        if (p < end && (*p == '+' || *p == '-')) p++;
        const char *first = p;
        while (p < end && is_digit(*p)) p++;
        if (p == first) return NOT_PLAIN;
    }
    size_t len = (size_t)(p - s);
    if (len > MAX_TOKEN) return NOT_PLAIN;
    double value;
    if (exact && mantissa <= (UINT64_C(1) << 53) && decimals <= 22) {
        value = (double)mantissa / POW10[decimals]; /* both exact: one correctly rounded division */
        if (negative) value = -value;
    } else {
        char token[MAX_TOKEN + 1];
        char *stop;
        memcpy(token, s, len);
        token[len] = '\0';
        value = strtod(token, &stop);
        if (stop != token + len || !isfinite(value)) return NOT_PLAIN;
    }
    *out = value;
    *cursor = p;
    return 0;
}

typedef struct {
    double *out; /* ncols rows of cap numbers each */
    Py_ssize_t cap, rows;
    int ncols;
} Table;

/* One line without its line end: skipped, a row added, or NOT_PLAIN. */
static int parse_line(Table *t, const char *s, size_t len) {
    if (len == 0) return 0;
    if (s[0] == '#') { /* pandas decodes comments as UTF-8 and ends lines at a lone \r: leave those to it */
        for (size_t i = 0; i < len; i++) {
            unsigned char c = (unsigned char)s[i];
            if (c >= 0x80 || (c < 0x20 && c != '\t')) return NOT_PLAIN;
        }
        return 0;
    }
    if (t->rows >= t->cap) return NOT_PLAIN;
    const char *p = s, *end = s + len;
    double *cell = t->out + t->rows;
    for (int j = 0; j < t->ncols; j++, cell += t->cap) {
        if (parse_number(&p, end, cell) != 0) return NOT_PLAIN;
        if (j < t->ncols - 1) { /* exactly one space between numbers, none after the last */
            if (p == end || *p != ' ') return NOT_PLAIN;
            p++;
        } else if (p != end) {
            return NOT_PLAIN;
        }
    }
    t->rows++;
    return 0;
}

/* Every line of the file, read in blocks; rows, NOT_PLAIN or READ_ERROR. */
static Py_ssize_t parse_file(const char *path, Table *t) {
    FILE *f = fopen(path, "rb");
    if (f == NULL) return READ_ERROR;
    char *buf = malloc(BLOCK_BYTES);
    if (buf == NULL) {
        fclose(f);
        return READ_ERROR;
    }
    Py_ssize_t result = 0;
    size_t have = 0;
    int first_block = 1, at_end = 0;
    while (!at_end && result == 0) {
        size_t got = fread(buf + have, 1, BLOCK_BYTES - have, f);
        if (ferror(f)) {
            result = READ_ERROR;
            break;
        }
        at_end = got < BLOCK_BYTES - have;
        have += got;
        size_t start = 0;
        if (first_block && have >= 3 && memcmp(buf, "\xef\xbb\xbf", 3) == 0) start = 3;
        first_block = 0;
        while (start < have) {
            char *newline = memchr(buf + start, '\n', have - start);
            if (newline == NULL && !at_end) break; /* the rest of this line is in the next block */
            size_t end = newline ? (size_t)(newline - buf) : have;
            size_t stop = end > start && buf[end - 1] == '\r' ? end - 1 : end;
            if (parse_line(t, buf + start, stop - start) != 0) {
                result = NOT_PLAIN;
                break;
            }
            start = end + 1;
        }
        if (start < have && !at_end) {
            if (start == 0) result = NOT_PLAIN; /* a line longer than a block */
            memmove(buf, buf + start, have - start);
            have -= start;
        } else {
            have = 0;
        }
    }
    free(buf);
    fclose(f);
    return result == 0 ? t->rows : result;
}

static PyObject *read_columns(PyObject *self, PyObject *args) {
    PyObject *path_obj;
    Py_buffer view;
    int ncols;
    (void)self;
    if (!PyArg_ParseTuple(args, "O&w*i", PyUnicode_FSConverter, &path_obj, &view, &ncols)) return NULL;
    Py_ssize_t result = NOT_PLAIN;
    if (ncols > 0 && view.len >= (Py_ssize_t)sizeof(double) * ncols) {
        Table t = {(double *)view.buf, view.len / ((Py_ssize_t)sizeof(double) * ncols), 0, ncols};
        const char *path = PyBytes_AS_STRING(path_obj);
        Py_BEGIN_ALLOW_THREADS
        result = parse_file(path, &t);
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&view);
    Py_DECREF(path_obj);
    return PyLong_FromSsize_t(result);
}

static PyMethodDef methods[] = {
    {"read_columns", read_columns, METH_VARARGS,
     "read_columns(path, out, ncols) -> rows, or -1 (not plain: use the strict path), -2 (cannot read).\n"
     "out: writable buffer of ncols * cap float64, filled column-major (out[j * cap + row])."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_numtext", NULL, -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__numtext(void) { return PyModule_Create(&module); }
