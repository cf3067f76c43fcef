/* webproto: the web pages' protocols, pure: an HTTP/1.1 request head (RFC 9112) and WebSocket
 * frames (RFC 6455), parsed from a caller's bytes and written into a caller's buffer. The I/O
 * is webserve.c's, on the process's loop. */
#ifndef TOOLS_WEBPROTO_H
#define TOOLS_WEBPROTO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define WEBREQ_HEAD_MAX 8192    /* a request head longer than this is refused (431) */
#define WEBREQ_HEADERS_MAX 64

/* The parts of a request the pages' server looks at; the others are checked and skipped. */
typedef struct {
    char method[8];
    char path[256];             /* the target without its query */
    int minor;                  /* HTTP/1.minor */
    char host[128], origin[160], key[64], version[8];
    bool has_host, upgrade_ws;  /* Upgrade: websocket */
    bool conn_upgrade, conn_close, conn_keep_alive;
    bool has_body;              /* Content-Length > 0 or Transfer-Encoding: not served */
} webreq_t;

/* Parses one request head from buf[0..len). Returns the bytes of the head (blank line
 * included) with *r filled, 0 when the head is not complete yet, or -1 when it is malformed:
 * *status is the HTTP status to answer (400, 414, 431, 505) and *why says what was wrong. */
int webreq_parse(webreq_t *r, const char *buf, size_t len, int *status, const char **why);

/* Sec-WebSocket-Accept for a client's key (24 characters of base64 for 16 bytes) into out:
 * 0, or -1 with errno EINVAL for a key of another form. */
int webws_accept(const char *key, char out[29]);

enum { WEBWS_CONT = 0, WEBWS_TEXT = 1, WEBWS_BINARY = 2, WEBWS_CLOSE = 8, WEBWS_PING = 9, WEBWS_PONG = 10 };

typedef struct {
    bool fin, masked;
    int op;
    uint8_t mask[4];
    uint64_t len;               /* payload bytes */
} webws_frame_t;

/* Parses a frame's header from buf[0..len): returns its length (2 to 14) with *f filled, 0 when
 * more bytes are needed, or -1 with *why for a frame no client may send (reserved bits or
 * opcode, a fragmented or long control frame, a length over 2^63). */
int webws_parse(webws_frame_t *f, const uint8_t *buf, size_t len, const char **why);
/* Unmasks n payload bytes that start `at` bytes into the payload. */
void webws_unmask(uint8_t *p, size_t n, const uint8_t mask[4], uint64_t at);
/* Writes a server's (unmasked, final) frame header for op and len into out: its length (2..10). */
size_t webws_head(uint8_t out[10], int op, uint64_t len);

#ifdef __cplusplus
}
#endif
#endif
