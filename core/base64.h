/* base64: RFC 4648 base64 text of bytes and back, for text transports (the XML bridge, the
 * viewer's JSON). Pure functions over caller buffers. */
#ifndef MARIE_BASE64_H
#define MARIE_BASE64_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Characters the text of n bytes takes (padding included, no terminator). */
size_t marie_base64_len(size_t n);
/* Writes marie_base64_len(n) characters to out; no terminator. */
void marie_base64_encode(char *out, const void *data, size_t n);
/* Bytes that s[0..len) decodes to, ignoring whitespace (space, tab, CR, LF); -1 when it is not
 * base64 (a foreign character, characters after padding, a count not a multiple of 4). */
long marie_base64_decoded_len(const char *s, size_t len);
/* Decodes s[0..len) into out (cap bytes): the byte count, or -1 when it is not base64 or does
 * not fit (nothing useful is in out then). */
long marie_base64_decode(const char *s, size_t len, uint8_t *out, size_t cap);

#ifdef __cplusplus
}
#endif
#endif
