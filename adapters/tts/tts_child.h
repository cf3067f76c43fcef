/* tts_child: one synthesis by an external synthesizer process (Festival's text2wave): text on
 * its stdin, a WAVE stream read from its stdout through the component's loop, so the loop never
 * blocks while Festival works and a stuck synthesis can be killed. */
#ifndef MARIE_TTS_CHILD_H
#define MARIE_TTS_CHILD_H
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "core/loop.h"

typedef struct tts_child tts_child_t;

/* Called once: pcm (mono 16-bit at rate) and n samples, or NULL with a reason. */
typedef void (*tts_child_done_cb_t)(const int16_t *pcm, size_t n, int rate, const char *why, void *user);

/* Splits a command line in place into at most max - 1 words and a NULL, as a shell splits a
 * simple one: words between spaces or tabs, and '...' or "..." inside a word taken as they are
 * (the quotes dropped; no escapes, no variables). The number of words, or -1 (a quote not
 * closed, or too many words). */
int tts_split_command(char *line, char *argv[], int max);

/* argv: the command (NULL-terminated). NULL with errno when it cannot be started. */
tts_child_t *tts_child_start(marie_loop_t *loop, char *const argv[], const char *text,
                             tts_child_done_cb_t cb, void *user);
/* Kills a synthesis in progress (no callback); NULL is a no-op. */
void tts_child_cancel(tts_child_t *t);

#endif
