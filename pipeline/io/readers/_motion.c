/* Bulk parser for a BVH MOTION block: whitespace-separated decimal numbers, one frame per line.
 *
 * parse(data: bytes, frames: int, channels: int) -> bytes | None
 *   Returns frames*channels native doubles (row-major), or None if anything is off: a line with another
 *   count of values, another number of non-blank lines than `frames`, a token that is not a plain finite
 *   decimal number ([+-]digits[.digits][(e|E)[+-]digits]), or a non-ASCII byte. The Python caller then
 *   runs its line-by-line diagnosis, which names the line and value; this module never explains errors.
 *   The output is allocated only when the data can hold frames*channels values (a digit and a separator
 *   each), so a header claiming 10^9 frames costs nothing and a claim near 2^63 cannot overflow the size.
 *
 * Numbers are converted exactly (correctly rounded, bit-identical to Python's float()): Clinger's fast
 * path (an integer mantissa < 2^53 times or divided by an exact power of ten <= 1e22 is one correctly
 * rounded IEEE operation), and strtod for everything else.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static const double POW10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int is_space(unsigned char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

/* Parse one token [p, end). Returns 0 on success. */
static int parse_number(const char *p, const char *end, double *out) {
    const char *start = p;
    int negative = 0;
    if (p < end && (*p == '+' || *p == '-')) negative = (*p++ == '-');
    uint64_t mantissa = 0;
    int significant = 0, frac_digits = 0, truncated = 0, any = 0;
    while (p < end && *p >= '0' && *p <= '9') {
        any = 1;
        if (significant < 19) {
            mantissa = mantissa * 10 + (uint64_t)(*p - '0');
            if (mantissa) significant++;
        } else {
            truncated = 1;
        }
        p++;
    }
    if (p < end && *p == '.') {
        p++;
        while (p < end && *p >= '0' && *p <= '9') {
            any = 1;
            if (significant < 19) {
                mantissa = mantissa * 10 + (uint64_t)(*p - '0');
                if (mantissa) significant++;
                frac_digits++;
            } else {
                truncated = 1;
            }
            p++;
        }
    }
    if (!any) return -1;
    int exponent = 0;
    if (p < end && (*p == 'e' || *p == 'E')) {
        p++;
        int exp_negative = 0;
        if (p < end && (*p == '+' || *p == '-')) exp_negative = (*p++ == '-');
        if (p >= end || *p < '0' || *p > '9') return -1;
        while (p < end && *p >= '0' && *p <= '9') {
            if (exponent < 100000) exponent = exponent * 10 + (*p - '0');
            p++;
        }
        if (exp_negative) exponent = -exponent;
    }
    if (p != end) return -1;
    int e10 = exponent - frac_digits;
    double value;
    if (!truncated && mantissa <= (UINT64_C(1) << 53) && e10 >= -22 && e10 <= 22) {
        value = (double)mantissa;
        value = e10 >= 0 ? value * POW10[e10] : value / POW10[-e10];
    } else {
        /* strtod needs a terminated string; a token of any length is a valid number to Python's float() */
        char buffer[128];
        size_t n = (size_t)(end - start);
        char *text = n < sizeof(buffer) ? buffer : (char *)malloc(n + 1);
        if (!text) return -1;
        memcpy(text, start, n);
        text[n] = '\0';
        value = strtod(text, NULL);
        if (text != buffer) free(text);
        if (value - value != 0) return -1; /* inf or nan */
        *out = value;
        return 0;
    }
    *out = negative ? -value : value;
    return 0;
}

static PyObject *parse(PyObject *self, PyObject *args) {
    Py_buffer view;
    Py_ssize_t frames, channels;
    if (!PyArg_ParseTuple(args, "y*nn", &view, &frames, &channels)) return NULL;
    if (frames <= 0 || channels <= 0 || frames > PY_SSIZE_T_MAX / (Py_ssize_t)sizeof(double) / channels ||
        frames * channels > (view.len + 1) / 2) {
        PyBuffer_Release(&view);
        Py_RETURN_NONE;
    }
    PyObject *result = PyBytes_FromStringAndSize(NULL, frames * channels * (Py_ssize_t)sizeof(double));
    if (!result) {
        PyBuffer_Release(&view);
        return NULL;
    }
    double *values = (double *)PyBytes_AS_STRING(result);
    const char *p = (const char *)view.buf;
    const char *end = p + view.len;
    Py_ssize_t line = 0, col = 0, total = 0;
    int ok = 1;
    while (p < end && ok) {
        unsigned char c = (unsigned char)*p;
        if (c == '\n') {
            if (col) {
                if (col != channels) ok = 0;
                line++;
                col = 0;
            }
            p++;
        } else if (is_space(c)) {
            p++;
        } else {
            const char *t = p;
            while (p < end && !is_space((unsigned char)*p) && *p != '\n') {
                if ((unsigned char)*p >= 128) ok = 0;
                p++;
            }
            if (!ok || line >= frames || col >= channels) {
                ok = 0;
                break;
            }
            if (parse_number(t, p, &values[total]) != 0) {
                ok = 0;
                break;
            }
            total++;
            col++;
        }
    }
    if (ok && col) {
        if (col != channels) ok = 0;
        line++;
    }
    PyBuffer_Release(&view);
    if (!ok || line != frames || total != frames * channels) {
        Py_DECREF(result);
        Py_RETURN_NONE;
    }
    return result;
}

static PyMethodDef METHODS[] = {
    {"parse", parse, METH_VARARGS, "parse(data, frames, channels) -> bytes of float64, or None"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_motion", "Bulk BVH MOTION parser.", -1, METHODS};

PyMODINIT_FUNC PyInit__motion(void) { return PyModule_Create(&MODULE); }
