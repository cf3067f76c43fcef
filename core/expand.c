/* expand: environment references in parameter strings, so that one system file serves every run. */
#include "core/expand.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

static int append(char **buf, size_t *len, size_t *cap, const char *s, size_t n)
{
    if (*len + n + 1 > *cap) {
        size_t c = (*cap ? *cap : 64);
        while (c < *len + n + 1)
            c *= 2;
        char *b = realloc(*buf, c);
        if (!b)
            return -1;
        *buf = b;
        *cap = c;
    }
    memcpy(*buf + *len, s, n);
    *len += n;
    (*buf)[*len] = '\0';
    return 0;
}

/* One "${...}" whose inside is [p, end): its value, or NULL with why set. */
static const char *lookup(const char *p, const char *end, size_t *vlen, char *why, size_t why_len)
{
    const char *sep = memmem(p, (size_t)(end - p), ":-", 2);
    size_t nlen = (size_t)((sep ? sep : end) - p);
    char name[128];
    if (nlen == 0 || nlen >= sizeof name) {
        snprintf(why, why_len, "bad variable name in '${%.*s}'", (int)(end - p), p);
        return NULL;
    }
    memcpy(name, p, nlen);
    name[nlen] = '\0';
    const char *v = getenv(name);
    if (v && *v) {
        *vlen = strlen(v);
        return v;
    }
    if (sep) {
        *vlen = (size_t)(end - sep - 2);
        return sep + 2;
    }
    snprintf(why, why_len, "environment variable %s is not set (write ${%s:-DEFAULT} for a default)", name, name);
    return NULL;
}

char *marie_expand_env(const char *in, char *why, size_t why_len)
{
    char *buf = NULL;
    size_t len = 0, cap = 0;
    if (append(&buf, &len, &cap, "", 0) < 0)
        goto err_nomem;
    for (const char *p = in; *p;) {
        const char *d = strstr(p, "${");
        if (!d) {
            if (append(&buf, &len, &cap, p, strlen(p)) < 0)
                goto err_nomem;
            break;
        }
        const char *end = strchr(d + 2, '}');
        if (!end) {
            snprintf(why, why_len, "unclosed '${' in '%s'", in);
            goto err_inval;
        }
        size_t vlen = 0;
        const char *v = lookup(d + 2, end, &vlen, why, why_len);
        if (!v)
            goto err_inval;
        if (append(&buf, &len, &cap, p, (size_t)(d - p)) < 0 || append(&buf, &len, &cap, v, vlen) < 0)
            goto err_nomem;
        p = end + 1;
    }
    return buf;
err_inval:
    free(buf);
    return marie_fail_null(EINVAL);
err_nomem:
    free(buf);
    return marie_fail_null(ENOMEM);
}

/* The index of the argument named by the inside of a "${...}" [p, end), or -1. */
static int arg_of(const char *p, const char *end, char *const *args, size_t nargs)
{
    const char *sep = memmem(p, (size_t)(end - p), ":-", 2);
    size_t nlen = (size_t)((sep ? sep : end) - p);
    for (size_t i = 0; i < nargs; i++)
        if (strncmp(args[i], p, nlen) == 0 && args[i][nlen] == '=')
            return (int)i;
    return -1;
}

char *marie_expand_args(const char *in, char *const *args, size_t nargs, int *used, char *why, size_t why_len)
{
    for (size_t i = 0; i < nargs; i++) {
        const char *eq = strchr(args[i], '=');
        if (!eq || eq == args[i] || strcspn(args[i], "${}:") < (size_t)(eq - args[i])) {
            snprintf(why, why_len, "launch argument '%s': expected name=value", args[i]);
            return marie_fail_null(EINVAL);
        }
    }
    char *buf = NULL;
    size_t len = 0, cap = 0;
    if (append(&buf, &len, &cap, "", 0) < 0)
        goto err_nomem;
    for (const char *p = in; *p;) {
        const char *d = strstr(p, "${"), *end = d ? strchr(d + 2, '}') : NULL;
        int k = end ? arg_of(d + 2, end, args, nargs) : -1;
        if (!end || k < 0) {        /* not ours: kept, up to and past it */
            size_t n = end ? (size_t)(end + 1 - p) : strlen(p);
            if (append(&buf, &len, &cap, p, n) < 0)
                goto err_nomem;
            p += n;
            continue;
        }
        const char *v = strchr(args[k], '=') + 1;
        if (used)
            used[k] = 1;
        if (append(&buf, &len, &cap, p, (size_t)(d - p)) < 0 || append(&buf, &len, &cap, v, strlen(v)) < 0)
            goto err_nomem;
        p = end + 1;
    }
    return buf;
err_nomem:
    free(buf);
    return marie_fail_null(ENOMEM);
}
