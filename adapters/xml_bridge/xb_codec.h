/* xb_codec: one XML element tree <-> the LCM wire format of a message, driven by the type
 * descriptors (core/typeinfo.h), so every type in lcmtypes/ is bridged by the same code; and
 * the text forms of values it uses (xb_text.c). */
#ifndef XB_CODEC_H
#define XB_CODEC_H

#include <stddef.h>
#include <stdint.h>

#include "adapters/xml_bridge/xb_doc.h"
#include "core/buf.h"
#include "core/typeinfo.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Appends s escaped for XML text or attribute values (", <, &, >, and \t \n \r as character
 * references, so a document stays on one line). */
int xb_escape(marie_buf_t *b, const char *s, size_t len);

/* Encodes `msg` (an element whose children are the fields; NULL for an all-zero message) as a
 * complete LCM payload of type t: fingerprint then fields. Returns 0, or -1 with err set
 * (codes: unknown-field, bad-value, bad-length, too-large). */
int xb_encode(const marie_typeinfo_t *t, const xb_node_t *msg, marie_buf_t *out, xb_error_t *err);

/* Appends the fields of the LCM payload `data` (fingerprint first) as XML child elements.
 * A payload that components would refuse (marie_typeinfo_check, what marie_decode_checked
 * applies: trailing bytes included) is refused too. Returns 0, or -1 with err set
 * (bad-fingerprint, bad-message, too-large). On failure the buffer is left at its length on
 * entry. */
int xb_decode(const marie_typeinfo_t *t, const void *data, size_t len, marie_buf_t *out, xb_error_t *err);

/* The value syntax of one scalar: integers in decimal, booleans true/false/1/0, reals as
 * C/XSD decimals including NaN, INF, -INF. Returns 0 or -1 (not a value of that type). */
int xb_parse_int(marie_prim_t prim, const char *s, size_t len, int64_t *v);
int xb_parse_real(marie_prim_t prim, const char *s, size_t len, double *v);
/* Shortest text that reads back to the same float/double. buf >= 32 bytes. */
void xb_format_real(marie_prim_t prim, double v, char *buf, size_t size);

/* The base64 text of bytes (core/base64.h) appended to b. 0 or -1. */
int xb_base64_encode(marie_buf_t *b, const uint8_t *data, size_t len);

/* XML whitespace. */
static inline int xb_is_ws(char c)
{
    return c == ' ' || c == '\t' || c == '\n' || c == '\r';
}

/* Nonzero when the bytes are valid UTF-8 made only of characters XML 1.0 allows. */
int xb_xml_safe(const char *s, size_t len);

#ifdef __cplusplus
}
#endif
#endif
