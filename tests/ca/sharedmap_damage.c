/* sharedmap_damage: damaged SharedMap logs and the map that must survive them. */
#include "tests/ca/sharedmap_damage.h"

#include <stdio.h>
#include <string.h>

#include "ca/sharedmap_log.h"

void smd_init(smd_log_t *l)
{
    memcpy(l->img, sharedmap_log_magic, SHAREDMAP_LOG_MAGIC_LEN);
    l->len = SHAREDMAP_LOG_MAGIC_LEN;
    l->n = 0;
}

void smd_add(smd_log_t *l, int op, const char *key, const uint8_t *data, size_t len)
{
    smd_rec_t *r = &l->r[l->n];
    *r = (smd_rec_t){ .op = op, .len = len, .version = l->n + 1, .utime = 1000 + l->n };
    snprintf(r->key, sizeof r->key, "%s", key);
    memcpy(r->data, data, len);
    sharedmap_log_rec_t lr = { op, l->n + 1, r->version, r->utime, r->key,
                               op == SHAREDMAP_LOG_SET ? "marie.raw" : NULL, r->data, len };
    r->off = l->len;
    r->size = sharedmap_log_encode(l->img + l->len, &lr);
    r->now = (long)r->off;
    l->len += r->size;
    l->n++;
}

void smd_zero(uint8_t *img, size_t len, size_t at, size_t n)
{
    if (at < len)
        memset(img + at, 0, n < len - at ? n : len - at);
}

size_t smd_cut(smd_log_t *l, uint8_t *img, size_t len, size_t at, size_t n)
{
    if (at >= len)
        return len;
    if (n > len - at)
        n = len - at;
    memmove(img + at, img + at + n, len - at - n);
    for (int i = 0; i < l->n; i++) {
        smd_rec_t *r = &l->r[i];
        if (r->now < 0)
            continue;
        if ((size_t)r->now >= at + n)
            r->now -= (long)n;
        else if ((size_t)r->now >= at)
            /* its start is gone, unless the bytes before the cut begin it again (all
             * records start alike): smd_mark_touched() compares */
            r->now = r->now >= (long)n ? r->now - (long)n : -1;
    }
    return len - n;
}

int smd_mark_touched(smd_log_t *l, const uint8_t *img, size_t len)
{
    int n = 0;
    for (int i = 0; i < l->n; i++) {
        smd_rec_t *r = &l->r[i];
        r->touched = r->now < 0 || (size_t)r->now + r->size > len ||
                     memcmp(img + r->now, l->img + r->off, r->size) != 0;
        n += r->touched;
    }
    return n;
}

int smd_check_map(const sharedmap_t *sm, const smd_log_t *l, char *why, size_t cap)
{
    const smd_rec_t *ref[SMD_MAXREC];
    int n = 0;
    int64_t version = 0;
    for (int i = 0; i < l->n; i++) {
        const smd_rec_t *r = &l->r[i];
        if (r->touched)
            continue;
        int k = 0;
        while (k < n && strcmp(ref[k]->key, r->key) != 0)
            k++;
        if (r->op == SHAREDMAP_LOG_SET)
            ref[k == n ? n++ : k] = r;
        else if (k < n)
            ref[k] = ref[--n];
        version = r->version;
    }
    if (sharedmap_size(sm) != (size_t)n) {
        snprintf(why, cap, "%zu keys, expected %d", sharedmap_size(sm), n);
        return -1;
    }
    for (int k = 0; k < n; k++) {
        sharedmap_value_t v;
        if (sharedmap_get(sm, ref[k]->key, &v) < 0 || v.len != ref[k]->len ||
            memcmp(v.data, ref[k]->data, v.len) != 0 || v.version != ref[k]->version ||
            v.set_utime != ref[k]->utime) {
            snprintf(why, cap, "key %s: missing or not the value of version %lld", ref[k]->key,
                     (long long)ref[k]->version);
            return -1;
        }
    }
    if (sharedmap_version(sm) != version) {
        snprintf(why, cap, "map version %lld, expected %lld", (long long)sharedmap_version(sm),
                 (long long)version);
        return -1;
    }
    return 0;
}
