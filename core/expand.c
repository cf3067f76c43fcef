/* expand: environment references in parameter strings, so that one system file serves every run. */
#include "core/expand.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/buf.h"
#include "core/err.h"

/* NAME's value among "NAME=value" (or bare "NAME": set, value unknown) entries, else the
 * environment's; NULL when unset. */
static const char *value_of(const char *name, char *const *extra, size_t nextra)
{
    size_t nl = strlen(name);
    for (size_t i = 0; i < nextra; i++)
        if (strncmp(extra[i], name, nl) == 0 && (extra[i][nl] == '=' || extra[i][nl] == 0))
            return extra[i][nl] == '=' ? extra[i] + nl + 1 : "?";
    return getenv(name);
}

/* One "${...}" whose inside is [p, end): its value, or NULL with why set. */
static const char *lookup(const char *p, const char *end, char *const *extra, size_t nextra, size_t *vlen,
                          char *why, size_t why_len)
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
    const char *v = value_of(name, extra, nextra);
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

static char *expand(const char *in, char *const *extra, size_t nextra, char *why, size_t why_len)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    if (marie_buf_put(&b, "", 0) < 0)       /* "" in, "" out */
        goto err_nomem;
    for (const char *p = in; *p;) {
        const char *d = strstr(p, "${");
        if (!d) {
            if (marie_buf_put(&b, p, strlen(p)) < 0)
                goto err_nomem;
            break;
        }
        const char *end = strchr(d + 2, '}');
        if (!end) {
            snprintf(why, why_len, "unclosed '${' in '%s'", in);
            goto err_inval;
        }
        size_t vlen = 0;
        const char *v = lookup(d + 2, end, extra, nextra, &vlen, why, why_len);
        if (!v)
            goto err_inval;
        if (marie_buf_put(&b, p, (size_t)(d - p)) < 0 || marie_buf_put(&b, v, vlen) < 0)
            goto err_nomem;
        p = end + 1;
    }
    return b.data;
err_inval:
    marie_buf_free(&b);
    return marie_fail_null(EINVAL);
err_nomem:
    marie_buf_free(&b);
    return marie_fail_null(ENOMEM);
}

char *marie_expand_env(const char *in, char *why, size_t why_len)
{
    return expand(in, NULL, 0, why, why_len);
}

int marie_expand_check(const char *in, char *const *extra, size_t nextra, char *why, size_t why_len)
{
    char *out = expand(in, extra, nextra, why, why_len);
    free(out);
    return out ? 0 : -1;
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
    marie_buf_t b;
    marie_buf_init(&b, 0);
    if (marie_buf_put(&b, "", 0) < 0)       /* "" in, "" out */
        goto err_nomem;
    for (const char *p = in; *p;) {
        const char *d = strstr(p, "${"), *end = d ? strchr(d + 2, '}') : NULL;
        int k = end ? arg_of(d + 2, end, args, nargs) : -1;
        if (!end || k < 0) {        /* not ours: kept, up to and past it */
            size_t n = end ? (size_t)(end + 1 - p) : strlen(p);
            if (marie_buf_put(&b, p, n) < 0)
                goto err_nomem;
            p += n;
            continue;
        }
        const char *v = strchr(args[k], '=') + 1;
        if (used)
            used[k] = 1;
        if (marie_buf_put(&b, p, (size_t)(d - p)) < 0 || marie_buf_put(&b, v, strlen(v)) < 0)
            goto err_nomem;
        p = end + 1;
    }
    return b.data;
err_nomem:
    marie_buf_free(&b);
    return marie_fail_null(ENOMEM);
}
