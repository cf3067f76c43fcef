/* am_settings: a system file's manager settings checked (managers/am_settings.h). */
#include "managers/am_settings.h"

#include "core/config.h"

int marie_am_check_system(const marie_system_t *sys, marie_am_settings_t *st, marie_errors_t *errs)
{
    marie_am_settings_t def = {2.0, 200.0, 1 << 20, 3};
    *st = def;
    int rc = balance_read_cfg(sys, &st->balance, errs);
    const marie_node_t *m = marie_node_get(marie_doc_root(sys->doc), "manager");
    if (!m)
        return rc;
    static const char *const keys[] = {"status_hz", "log_rate", "log_max_bytes", "log_keep", NULL};
    if (m->kind != MARIE_NODE_MAP) {
        marie_errors_add(errs, m->file, m->line, m->col, "manager: expected a mapping");
        return -1;
    }
    if (marie_node_check_keys(m, keys, "manager", errs) < 0)
        return -1;
    const marie_node_t *v;
    int64_t iv = 0;
    if ((v = marie_node_get(m, "status_hz"))) {
        if (marie_node_double(v, &st->status_hz, errs) < 0)
            rc = -1;
        else if (st->status_hz < 0.5 || st->status_hz > 50) {
            marie_errors_add(errs, v->file, v->line, v->col, "status_hz: expected 0.5 to 50");
            rc = -1;
        }
    }
    if ((v = marie_node_get(m, "log_rate")) && marie_node_double(v, &st->log_rate, errs) < 0)
        rc = -1;
    if ((v = marie_node_get(m, "log_max_bytes"))) {
        if (marie_node_int(v, &iv, errs) < 0) {
            rc = -1;
        } else if (iv < 4096) {
            marie_errors_add(errs, v->file, v->line, v->col, "log_max_bytes: at least 4096");
            rc = -1;
        } else {
            st->log_max_bytes = iv;
        }
    }
    if ((v = marie_node_get(m, "log_keep"))) {
        if (marie_node_int(v, &iv, errs) < 0) {
            rc = -1;
        } else if (iv < 1 || iv > 100) {
            marie_errors_add(errs, v->file, v->line, v->col, "log_keep: expected 1 to 100");
            rc = -1;
        } else {
            st->log_keep = (int)iv;
        }
    }
    return rc;
}
