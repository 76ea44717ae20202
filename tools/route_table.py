#!/usr/bin/env python3
"""The warehouse-loop table of docs/routes.md: 100-run sweeps of
firmware-sim/scenarios/warehouse_loop.toml for each estimator, the start
heading known (the scenario: along the first leg, start =
"as_given_heading_known", the estimator is told) and swept (uniform, start
= "as_given": the estimator is not told).

    python3 tools/route_table.py [RUNS]   # from the repository root; default 100

Each variant is the scenario file with its [estimator.fusion] table
replaced, written to target/route-table/; the sweeps' outputs go there too.
"""

import json
import pathlib
import subprocess
import sys

RUNS = int(sys.argv[1]) if len(sys.argv) > 1 else 100
ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "target" / "route-table"
SCENARIO = (ROOT / "firmware-sim/scenarios/warehouse_loop.toml").read_text()
# The fusion filters keep the scenario's fix age (the reader's period of
# latency, docs/fusion.md); the observers take the tag as it comes.
LATENCY = ('fix_latency_s = 0.01            # a fix is a period old: the reader reads at '
           'a tick, polled at the next\n')
EKF = '[estimator.fusion]\nfilter = "ekf"\n' + LATENCY
ESTIMATORS = [
    ("fusion EKF", EKF),
    ("paper 001's observer (5)", ""),
    ("paper 002's pose observer", "[estimator.pose_observer]\n"),
    ("fusion UKF", '[estimator.fusion]\nfilter = "ukf"\n' + LATENCY),
    ("fusion particle filter (100)",
     '[estimator.fusion]\nfilter = "particle_filter"\n' + LATENCY),
]
KNOWN_HEADING = 'initial_heading = "scenario"'
KNOWN_START = 'start = "as_given_heading_known"'
HEADINGS = [
    ("known", KNOWN_HEADING, KNOWN_START),
    ("any", 'initial_heading = "any"', 'start = "as_given"'),
]

assert EKF in SCENARIO, "warehouse_loop.toml no longer has its EKF table"
assert KNOWN_HEADING in SCENARIO and KNOWN_START in SCENARIO, \
    "warehouse_loop.toml no longer starts parked, its heading known"
OUT.mkdir(parents=True, exist_ok=True)
print("| estimator | start heading | done | stop position p50 / p90 / worst (m) "
      "| worst stop heading (°) | cross-track p50 / worst (m) | worst time ratio |")
print("| --- | --- | ---: | --- | ---: | --- | ---: |")
for e, (label, table) in enumerate(ESTIMATORS):
    for heading, line, start in HEADINGS:
        name = f"{e}-{heading}"
        text = (SCENARIO.replace(EKF, table).replace(KNOWN_HEADING, line)
                .replace(KNOWN_START, start))
        path = OUT / f"{name}.toml"
        path.write_text(text)
        subprocess.run(
            ["cargo", "run", "--release", "-q", "-p", "firmware-sim", "--", "sweep", str(path),
             "--runs", str(RUNS), "--no-plot", "--out", str(OUT / name)],
            cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
        s = json.loads((OUT / name / "summary.json").read_text())
        r = s["route"]
        sp, ct = r["stop_position_error_m"], r["cross_track_error_m"]
        worst = lambda k: r[k]["value"] if r[k] else float("nan")
        print(f"| {label} | {heading} | {r['runs_done']}/{s['runs']} "
              f"| {sp['p50']:.4f} / {sp['p90']:.4f} / {worst('worst_stop_position_error_m'):.4f} "
              f"| {worst('worst_stop_heading_error_deg'):.2f} "
              f"| {ct['p50']:.4f} / {worst('worst_cross_track_error_m'):.4f} "
              f"| {worst('worst_time_ratio'):.4f} |")
