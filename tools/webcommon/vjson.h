/* vjson: compact JSON for the viewer page: a growable text buffer, marie messages as JSON,
 * and the parser of the page's commands (flat JSON objects). */
#ifndef VIEWER_VJSON_H
#define VIEWER_VJSON_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "lcmtypes/marie_types.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    char *s;
    size_t len, cap;
    bool oom;                   /* an append failed: the text is incomplete */
} vj_buf_t;

void vj_init(vj_buf_t *b);
void vj_free(vj_buf_t *b);
void vj_reset(vj_buf_t *b);
void vj_raw(vj_buf_t *b, const char *s, size_t n);
void vj_lit(vj_buf_t *b, const char *s);
void vj_printf(vj_buf_t *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void vj_str(vj_buf_t *b, const char *s);        /* quoted and escaped; NULL gives "" */
void vj_num(vj_buf_t *b, double v, int prec);   /* non-finite values become null */
void vj_int(vj_buf_t *b, int64_t v);
void vj_base64(vj_buf_t *b, const void *data, size_t n);   /* quoted */

/* The type of an LCM payload by its fingerprint, or NULL. */
const marie_type_t *vj_type_of(const void *data, size_t len);

/* What a channel carries for the page. */
typedef enum {
    VJ_ROLE_OTHER = 0, VJ_ROLE_POSE, VJ_ROLE_TRUTH,
} vj_role_t;

/* Append the fields of a decoded message as `,"k":"laser",...` (no braces), for the page's
 * kinds; returns false (nothing appended) for types the page does not show. */
bool vj_message(vj_buf_t *b, const marie_type_t *t, const void *msg, vj_role_t role);
/* The page's short name of a type's kind ("laser", "pose", ...), or NULL. */
const char *vj_kind(const marie_type_t *t);

/* A command from the page: a flat object of string and number members. */
#define VJ_CMD_MAX 8
typedef struct {
    int n;
    char key[VJ_CMD_MAX][24];
    char str[VJ_CMD_MAX][128];  /* string values ("" for numbers) */
    double num[VJ_CMD_MAX];     /* number values (0 for strings) */
    bool is_num[VJ_CMD_MAX];
} vj_cmd_t;

/* Parse text[0..len). 0, or -EBADMSG on anything but a flat object of at most VJ_CMD_MAX
 * string/number/bool members with short keys and values. */
int vj_cmd_parse(vj_cmd_t *cmd, const char *text, size_t len);
const char *vj_cmd_str(const vj_cmd_t *cmd, const char *key);          /* NULL if absent or a number */
bool vj_cmd_num(const vj_cmd_t *cmd, const char *key, double *out);    /* false if absent or a string */

#ifdef __cplusplus
}
#endif
#endif
