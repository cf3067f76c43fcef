/* fuzz_mission_signs: any YAML given as a sign goal list is parsed or refused with errors,
 * never crashes, and a parsed list survives searching and reading. */
#include <stdint.h>
#include <stddef.h>

#include "adapters/mission/mission_signs.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_parse("signs.yaml", (const char *)data, size, &errs);
    if (doc) {
        mission_t m;
        mission_signs_t ss;
        mission_init(&m);
        if (mission_signs_parse(&ss, &m, marie_doc_root(doc), 0.3, &errs) > 0) {
            for (int i = 0; i < 6; i++) {
                double pose[3] = { m.current >= 0 ? m.goals[m.current].x : 0, m.current >= 0 ? m.goals[m.current].y : 0, 0 };
                mission_signs_steer(&ss, &m, pose, NULL, NULL);
                if (i == 2)
                    mission_signs_read(&ss, &m, ss.s[0].message, 1.0, 2.0, 0.5, 3.0, NULL, NULL);
                mission_update(&m, i * 1000000LL, pose, NULL, NULL);
            }
        }
        marie_doc_destroy(doc);
    }
    marie_errors_clear(&errs);
    return 0;
}
