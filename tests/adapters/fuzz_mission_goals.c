/* fuzz_mission_goals: any YAML given as a goal list is parsed or refused with errors, never crashes. */
#include <stdint.h>
#include <stddef.h>

#include "adapters/mission/mission.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_parse("goals.yaml", (const char *)data, size, &errs);
    if (doc) {
        mission_t m;
        mission_init(&m);
        if (mission_parse(&m, marie_doc_root(doc), 0.3, &errs) > 0) {
            double pose[3] = { 0, 0, 0 };
            for (int i = 0; i < 4; i++)
                mission_update(&m, i * 1000000LL, pose, NULL, NULL);
        }
        marie_doc_destroy(doc);
    }
    marie_errors_clear(&errs);
    return 0;
}
