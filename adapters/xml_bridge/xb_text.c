/* xb_text: the text forms of the XML bridge's values: XML escaping (into core/buf.h buffers),
 * base64, the syntax of integers and reals, and which strings XML can carry. */
#include "adapters/xml_bridge/xb_codec.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/base64.h"

/* ---- escaping ---- */

int xb_escape(marie_buf_t *b, const char *s, size_t len)
{
    size_t start = 0;
    for (size_t i = 0; i < len; i++) {
        const char *rep;
        switch (s[i]) {
        case '&': rep = "&amp;"; break;
        case '<': rep = "&lt;"; break;
        case '>': rep = "&gt;"; break;
        case '"': rep = "&quot;"; break;
        case '\t': rep = "&#9;"; break;
        case '\n': rep = "&#10;"; break;
        case '\r': rep = "&#13;"; break;
        default: continue;
        }
        if (marie_buf_put(b, s + start, i - start) < 0 || marie_buf_puts(b, rep) < 0)
            return -1;
        start = i + 1;
    }
    return marie_buf_put(b, s + start, len - start);
}

/* ---- base64 ---- */

int xb_base64_encode(marie_buf_t *b, const uint8_t *d, size_t len)
{
    if (marie_buf_reserve(b, marie_base64_len(len)) < 0)
        return -1;
    marie_base64_encode(b->data + b->len, d, len);
    b->len += marie_base64_len(len);
    return 0;
}

/* ---- scalar syntax ---- */

/* The text of s[0..len) without surrounding white space, as a C string in tmp[size]: 0, or -1
 * when nothing is left or it does not fit. */
static int trimmed(char *tmp, size_t size, const char *s, size_t len)
{
    while (len && xb_is_ws(*s)) {
        s++;
        len--;
    }
    while (len && xb_is_ws(s[len - 1]))
        len--;
    if (len == 0 || len >= size)
        return -1;
    memcpy(tmp, s, len);
    tmp[len] = '\0';
    return 0;
}

int xb_parse_int(marie_prim_t prim, const char *s, size_t len, int64_t *v)
{
    char tmp[64];
    if (trimmed(tmp, sizeof tmp, s, len) < 0)
        return -1;
    if (prim == MARIE_PRIM_BOOL) {
        if (!strcmp(tmp, "true") || !strcmp(tmp, "1"))
            *v = 1;
        else if (!strcmp(tmp, "false") || !strcmp(tmp, "0"))
            *v = 0;
        else
            return -1;
        return 0;
    }
    char *end;
    errno = 0;
    long long x = strtoll(tmp, &end, 10);
    if (errno || *end || end == tmp)
        return -1;
    switch (prim) {
    case MARIE_PRIM_INT8: if (x < INT8_MIN || x > INT8_MAX) return -1; break;
    case MARIE_PRIM_INT16: if (x < INT16_MIN || x > INT16_MAX) return -1; break;
    case MARIE_PRIM_INT32: if (x < INT32_MIN || x > INT32_MAX) return -1; break;
    case MARIE_PRIM_BYTE: if (x < 0 || x > 255) return -1; break;
    case MARIE_PRIM_INT64: break;
    default: return -1;
    }
    *v = x;
    return 0;
}

/* Powers of ten a double holds exactly. */
static const double exact_pow10[] = {
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
};
#define EXACT_POW10_MAX 22

/* Reads [+-]digits[.digits][e[+-]digits] with at most 15 significant digits and a scale of at
 * most 10^22 (Clinger's fast path): mantissa and power are then exact doubles, so one correctly
 * rounded multiplication or division gives what strtod gives, at a fraction of its cost (reals
 * are most of what a message document holds). -1 for anything else: strtod decides. */
static int parse_short_decimal(const char *s, size_t len, double *v)
{
    size_t i = 0;
    int neg = 0, digits = 0, frac = 0, any = 0;
    uint64_t m = 0;
    if (i < len && (s[i] == '-' || s[i] == '+'))
        neg = s[i++] == '-';
    for (int in_frac = 0;; i++) {
        if (i < len && s[i] == '.' && !in_frac) {
            in_frac = 1;
            continue;
        }
        if (i >= len || s[i] < '0' || s[i] > '9')
            break;
        any = 1;
        frac += in_frac;
        if (m == 0 && s[i] == '0')
            continue;           /* leading zeros are not significant */
        if (++digits > 15)
            return -1;
        m = m * 10 + (uint64_t)(s[i] - '0');
    }
    if (!any)
        return -1;
    int e = 0;
    if (i < len && (s[i] == 'e' || s[i] == 'E')) {
        int eneg = 0, ed = 0;
        i++;
        if (i < len && (s[i] == '-' || s[i] == '+'))
            eneg = s[i++] == '-';
        for (; i < len && s[i] >= '0' && s[i] <= '9' && ed < 4; i++, ed++)
            e = e * 10 + (s[i] - '0');
        if (ed == 0 || ed == 4)
            return -1;
        if (eneg)
            e = -e;
    }
    if (i != len)
        return -1;
    int scale = e - frac;
    if (scale < -EXACT_POW10_MAX || scale > EXACT_POW10_MAX)
        return -1;
    double x = (double)m;
    x = scale < 0 ? x / exact_pow10[-scale] : x * exact_pow10[scale];
    *v = neg ? -x : x;
    return 0;
}

int xb_parse_real(marie_prim_t prim, const char *s, size_t len, double *v)
{
    while (len && xb_is_ws(*s)) {
        s++;
        len--;
    }
    while (len && xb_is_ws(s[len - 1]))
        len--;
    double x;
    if (parse_short_decimal(s, len, &x) < 0) {
        char tmp[128];
        if (trimmed(tmp, sizeof tmp, s, len) < 0)
            return -1;
        char *end;
        errno = 0;
        x = strtod(tmp, &end);
        if (*end || end == tmp || (errno == ERANGE && isinf(x)))
            return -1;
    }
    if (prim == MARIE_PRIM_FLOAT && isfinite(x) && fabs(x) > FLT_MAX)
        return -1;
    /* One NaN: strtod's "-nan" has the sign bit set, which the bridge writes back as "NaN". */
    *v = isnan(x) ? NAN : x;
    return 0;
}

/* The "%.15g" text of a double that is the nearest to a decimal of at most 15 significant
 * digits in [1e-4, 1e15), found without printf: when N / 10^k (N < 10^15, both exact, one
 * correctly rounded division) gives v back, that decimal is what %.15g prints (15-digit
 * decimals are farther apart than a double's rounding error) and it reads back to v. Written
 * as %g writes it there: fixed notation, no trailing zeros. -1 for values outside that range,
 * -2 for those inside it that no such decimal gives back (then %.15g does not either). */
static int format_short_decimal(double v, char *buf, size_t size)
{
    double a = fabs(v);
    char *o = buf;
    if (size < 40)
        return -1;
    if (signbit(v))
        *o++ = '-';
    if (a == 0) {
        strcpy(o, "0");
        return 0;
    }
    if (!(a >= 1e-4 && a < 1e15))
        return -1;
    uint64_t n = 0;
    int k = 0;
    for (;; k++) {
        if (k > EXACT_POW10_MAX)
            return -2;
        double t = a * exact_pow10[k];
        if (t >= 1e15)
            return -2;
        n = (uint64_t)(t + 0.5);
        if (n < 1000000000000000ull && (double)n / exact_pow10[k] == a)
            break;
    }
    while (k > 0 && n % 10 == 0) {
        n /= 10;
        k--;
    }
    char dig[24];
    int nd = 0;
    do {
        dig[nd++] = (char)('0' + n % 10);
        n /= 10;
    } while (n);
    if (nd <= k) {                      /* 0.00ddd */
        *o++ = '0';
        *o++ = '.';
        for (int i = nd; i < k; i++)
            *o++ = '0';
        while (nd)
            *o++ = dig[--nd];
    } else {                            /* ddd[.ddd] */
        for (int i = nd; i > 0; i--) {
            if (i == k)
                *o++ = '.';
            *o++ = dig[i - 1];
        }
    }
    *o = '\0';
    return 0;
}

void xb_format_real(marie_prim_t prim, double v, char *buf, size_t size)
{
    int first = 15;
    if (prim != MARIE_PRIM_FLOAT && !isnan(v) && !isinf(v)) {
        int rc = format_short_decimal(v, buf, size);
        if (rc == 0)
            return;
        if (rc == -2)
            first = 16;
    }
    if (isnan(v)) {
        snprintf(buf, size, "NaN");
        return;
    }
    if (isinf(v)) {
        snprintf(buf, size, v < 0 ? "-INF" : "INF");
        return;
    }
    if (prim == MARIE_PRIM_FLOAT) {
        float f = (float)v;
        for (int prec = 6;; prec++) {
            snprintf(buf, size, "%.*g", prec, (double)f);
            if (prec == 9 || strtof(buf, NULL) == f)    /* 9 digits always read back */
                return;
        }
    }
    for (int prec = first;; prec++) {
        snprintf(buf, size, "%.*g", prec, v);
        if (prec == 17 || strtod(buf, NULL) == v)       /* 17 digits always read back */
            return;
    }
}

/* ---- XML safety of strings ---- */

int xb_xml_safe(const char *str, size_t len)
{
    const uint8_t *s = (const uint8_t *)str;
    size_t i = 0;
    while (i < len) {
        uint32_t c = s[i];
        size_t n;
        if (c < 0x80) {
            if (c < 0x20 && c != 0x9 && c != 0xA && c != 0xD)
                return 0;
            i++;
            continue;
        } else if ((c & 0xE0) == 0xC0) {
            n = 1; c &= 0x1F;
        } else if ((c & 0xF0) == 0xE0) {
            n = 2; c &= 0x0F;
        } else if ((c & 0xF8) == 0xF0) {
            n = 3; c &= 0x07;
        } else {
            return 0;
        }
        if (i + n >= len)
            return 0;
        for (size_t k = 1; k <= n; k++) {
            if ((s[i + k] & 0xC0) != 0x80)
                return 0;
            c = c << 6 | (s[i + k] & 0x3F);
        }
        if ((n == 1 && c < 0x80) || (n == 2 && c < 0x800) || (n == 3 && c < 0x10000) ||
            c > 0x10FFFF || (c >= 0xD800 && c <= 0xDFFF) || c == 0xFFFE || c == 0xFFFF)
            return 0;
        i += n + 1;
    }
    return 1;
}
