/* topic: marie topic list|echo|hz|pub (the program marie-topic): the channels on the bus, their
 * messages decoded from the type descriptors (marie's and users'), their rates, and messages
 * published from YAML. */
#ifndef MARIE_TOOLS_TOPIC_H
#define MARIE_TOOLS_TOPIC_H

#include <stddef.h>

#include "core/buf.h"
#include "core/config.h"
#include "core/typeinfo.h"

/* Encode `text` (a YAML or JSON mapping of the message's fields; '' or {} for all zero) as a
 * payload of t into out. 0, or -1 with "field.path: what" in why. */
int topic_encode(const marie_typeinfo_t *t, const char *text, marie_buf_t *out, char *why, size_t whylen);

#endif
