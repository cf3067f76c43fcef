/* fuzz_xml_bridge_doc: the XML bridge's document parser and codec on arbitrary bytes: streams cut
 * anywhere, every parsed document encoded as a message type, payloads decoded as any type. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/xml_bridge/xb_codec.h"
#include "adapters/xml_bridge/xb_doc.h"

typedef struct {
    const marie_typeinfo_t *t;
    marie_buf_t *out;
    int rc;
} again_t;

static void on_again(void *user, xb_node_t *root)
{
    again_t *a = user;
    xb_error_t err;
    a->rc = xb_encode(a->t, root, a->out, &err);
}

static void on_doc(void *user, xb_node_t *root)
{
    const uint8_t *sel = user;
    const char *tn = xb_node_attr(root, "type");
    const marie_typeinfo_t *t = tn ? marie_typeinfo_find(tn) : NULL;
    if (!t)
        t = marie_typeinfos[*sel % marie_typeinfos_count];
    marie_buf_t out, xml, again;
    xb_error_t err;
    marie_buf_init(&out, 1 << 20);
    marie_buf_init(&xml, 1 << 22);
    marie_buf_init(&again, 1 << 20);
    if (xb_encode(t, root, &out, &err) == 0) {
        /* Whatever encodes must decode, and the XML of it must encode to the same bytes. */
        if (marie_buf_puts(&xml, "<m>") < 0 || xb_decode(t, out.data, out.len, &xml, &err) != 0 ||
            marie_buf_puts(&xml, "</m>") < 0)
            abort();
        again_t a = { t, &again, -1 };
        xb_doc_parser_t *p = xb_doc_parser_create(NULL, on_again, &a);
        if (!p || xb_doc_parser_feed(p, xml.data, xml.len) != 0 || a.rc != 0 ||
            again.len != out.len || memcmp(again.data, out.data, out.len) != 0)
            abort();
        xb_doc_parser_destroy(p);
    }
    marie_buf_free(&out);
    marie_buf_free(&xml);
    marie_buf_free(&again);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    uint8_t sel = data[0];
    size_t cut = data[1] % (size - 1);
    data += 2;
    size -= 2;
    xb_doc_limits_t lim = { 1 << 16, 16 };
    xb_doc_parser_t *p = xb_doc_parser_create(&lim, on_doc, &sel);
    if (!p)
        return 0;
    if (xb_doc_parser_feed(p, data, cut) == 0)
        xb_doc_parser_feed(p, data + cut, size - cut);
    xb_doc_parser_destroy(p);

    /* The same bytes as an LCM payload of some type, with its fingerprint put in front. */
    const marie_typeinfo_t *t = marie_typeinfos[sel % marie_typeinfos_count];
    uint8_t *payload = malloc(size + 8);
    if (!payload)
        return 0;
    for (int i = 0; i < 8; i++)
        payload[i] = (uint8_t)((uint64_t)t->fingerprint >> (56 - 8 * i));
    memcpy(payload + 8, data, size);
    marie_buf_t xml;
    xb_error_t err;
    marie_buf_init(&xml, 1 << 22);
    xb_decode(t, payload, size + 8, &xml, &err);
    marie_buf_free(&xml);
    free(payload);
    return 0;
}
