/* vjson: compact JSON for the viewer page: JSON values, marie messages as JSON,
 * and the parser of the page's commands (flat JSON objects). */
#ifndef VIEWER_VJSON_H
#define VIEWER_VJSON_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/buf.h"
#include "core/typeinfo.h"

#ifdef __cplusplus
extern "C" {
#endif

/* JSON values appended to a text buffer (core/buf.h). */
void vj_str(marie_buf_t *b, const char *s);        /* quoted and escaped; NULL gives "" */
void vj_num(marie_buf_t *b, double v, int prec);   /* non-finite values become null */
void vj_int(marie_buf_t *b, int64_t v);
void vj_base64(marie_buf_t *b, const void *data, size_t n);   /* quoted */

/* The type of an LCM payload by its fingerprint, or NULL. */
const marie_type_t *vj_type_of(const void *data, size_t len);

/* What a channel carries for the page: a pose frame says whether it is the estimate or the
 * ground truth. */
typedef enum {
    VJ_ROLE_OTHER = 0, VJ_ROLE_POSE, VJ_ROLE_TRUTH,
} vj_role_t;

/* Append the message in an LCM payload (fingerprint first) as members of the page's frame:
 * `,"k":KIND,"role":"est"|"truth","msg":{...},"stride":{"FIELD":N,...}`, role only unless
 * VJ_ROLE_OTHER, stride only when an array was thinned. The body is written from the type's
 * descriptor (core/typeinfo.h), field names as in the .lcm file: structs as objects, arrays as
 * arrays, byte and int8 arrays as base64 strings, booleans as true/false, integers (int64
 * too) as numbers, floats with 7 and doubles with 10 significant digits, NaN and infinities
 * as null. KIND is the page's name of the type ("laser", "pose", ...), or the LCM type name
 * ("marie.gyro_t") for a type the page does not know. A kind may cap its top-level
 * variable-length arrays of numbers (laser 720 beams, particles 1500): a longer one is sent
 * as every N-th element. Returns 0, or -1 with errno EBADMSG (nothing appended) for an unknown type or a
 * payload that does not check (marie_typeinfo_check). */
int vj_message(marie_buf_t *b, const void *data, size_t len, vj_role_t role);
/* The page's name of a type's kind ("laser", "pose", ...), or NULL. */
const char *vj_kind(const marie_typeinfo_t *t);

/* A command from the page: a flat object of string and number members. */
#define VJ_CMD_MAX 8
typedef struct {
    int n;
    char key[VJ_CMD_MAX][24];
    char str[VJ_CMD_MAX][128];  /* string values ("" for numbers) */
    double num[VJ_CMD_MAX];     /* number values (0 for strings) */
    bool is_num[VJ_CMD_MAX];
} vj_cmd_t;

/* Parse text[0..len). 0, or -1 with errno EBADMSG on anything but a flat object of at most VJ_CMD_MAX
 * string/number/bool members with short keys and values. */
int vj_cmd_parse(vj_cmd_t *cmd, const char *text, size_t len);
const char *vj_cmd_str(const vj_cmd_t *cmd, const char *key);          /* NULL if absent or a number */
bool vj_cmd_num(const vj_cmd_t *cmd, const char *key, double *out);    /* false if absent or a string */

#ifdef __cplusplus
}
#endif
#endif
