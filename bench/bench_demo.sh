#!/bin/sh
# bench_demo: the whole robot application during the demo: CPU and memory of every component
# and manager (from the managers' status), run time and localization, as bench rows.
B=${B:-build}
out=$B/bench/demo
"$B/bin/marie-demo" --quiet --out "$out" > "$out.txt" 2>&1
python3 - "$out/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
rows = [("system_cpu_mean", s["system_cpu_percent"], "%core"), ("system_rss_peak", s["system_rss_mb"], "MB"),
        ("wall_time", s["wall_s"], "s"), ("sim_time", s["sim_s"], "s"),
        ("realtime_factor", s["sim_s"] / s["wall_s"], "x"), ("goals_reached", s["reached"], "of %d" % s["goals"]),
        ("localization_rms", s["rms"], "m"), ("localization_max", s["max"], "m")]
for name, v, unit in rows:
    print("demo\t%s\t%.3f\t%s\t-\t-" % (name, v, unit))
PY
