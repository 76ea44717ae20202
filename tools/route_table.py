#!/usr/bin/env python3
"""The warehouse-loop table of docs/routes.md: 100-run sweeps of
firmware-sim/scenarios/warehouse_loop.toml for each estimator, the start
heading known (the scenario: along the first leg, start =
"as_given_heading_known", the estimator is told) and swept (uniform, start
= "as_given": the estimator is not told).

    python3 tools/route_table.py [RUNS]             # from the repository root; default 100
    python3 tools/route_table.py [RUNS] --variants  # the fusion EKF (heading known) on
                                                    # variants of the floor, start and wheel noise

Each variant is the scenario file with its [estimator.fusion] table
replaced, written to target/route-table/; the sweeps' outputs go there too.
"""

import json
import pathlib
import subprocess
import sys

ARGS = [a for a in sys.argv[1:] if not a.startswith("--")]
RUNS = int(ARGS[0]) if ARGS else 100
VARIANTS = "--variants" in sys.argv[1:]
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


def sweep(name, text):
    """Sweeps the scenario `text` and returns its summary's route figures."""
    path = OUT / f"{name}.toml"
    path.write_text(text)
    subprocess.run(
        ["cargo", "run", "--release", "-q", "-p", "firmware-sim", "--", "sweep", str(path),
         "--runs", str(RUNS), "--no-plot", "--out", str(OUT / name)],
        cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    s = json.loads((OUT / name / "summary.json").read_text())
    return s, s["route"]


def row(s, r):
    """A table row's figures, from `done` on."""
    sp, ct = r["stop_position_error_m"], r["cross_track_error_m"]
    worst = lambda k: r[k]["value"] if r[k] else float("nan")
    return (f"{r['runs_done']}/{s['runs']} "
            f"| {sp['p50']:.4f} / {sp['p90']:.4f} / {worst('worst_stop_position_error_m'):.4f} "
            f"| {worst('worst_stop_heading_error_deg'):.2f} "
            f"| {ct['p50']:.4f} / {worst('worst_cross_track_error_m'):.4f} "
            f"| {worst('worst_time_ratio'):.4f} |")


def replaced(text, old, new):
    assert old in text, f"warehouse_loop.toml no longer has {old!r}"
    return text.replace(old, new)


if VARIANTS:
    WHEELS = "fix_latency_s = 0.01"
    SPACING, BAUD = "spacing_m = 0.1\n", "baud = 115200"
    RADIUS = "start_radius_m = [0.0, 0.05]"
    OFFSET, RANDOM = "offset_m = [0.0, 0.0]", "tag_offset = true"

    def wheels(v):
        return lambda t: replaced(t, WHEELS, f"wheel_variance_per_m = {v}\n{WHEELS}")

    def spacing(s):
        # A finer floor sends more frames: the line at 1 MBd carries them.
        return lambda t: replaced(replaced(t, SPACING, f"spacing_m = {s}\n"), BAUD, "baud = 1000000")

    def slipping(v):
        # The plant's wheels slip: each rolls with a travel variance of `v`
        # per metre (the filter keeps its own setting unless told).
        return lambda t: replaced(
            t, "substeps = 10\n",
            f"substeps = 10\n\n[plant.wheels]\ntravel_variance_m2_per_m = {v}\n")

    def on_station(t):
        return replaced(t, RADIUS, "start_radius_m = [0.0, 0.0]")

    def on_corners(t):
        # Tags at (0.05 + 0.1 i, 0.05 + 0.1 j): every station on a cell
        # corner, every leg on a row boundary.
        return replaced(replaced(t, OFFSET, "offset_m = [0.05, 0.05]"), RANDOM, "tag_offset = false")

    def both(*fs):
        def f(t):
            for g in fs:
                t = g(t)
            return t
        return f

    CASES = [
        ("as in the table", lambda t: t),
        ("filter wheel noise 1e-4 m²/m", wheels("1e-4")),
        ("filter wheel noise 1e-5 m²/m", wheels("1e-5")),
        ("filter wheel noise 1e-6 m²/m", wheels("1e-6")),
        ("wheels slipping 1e-6 m²/m, filter at its default", slipping("1e-6")),
        ("wheels slipping 1e-6 m²/m, filter matched", both(slipping("1e-6"), wheels("1e-6"))),
        ("wheels slipping 1e-5 m²/m, filter at its default", slipping("1e-5")),
        ("wheels slipping 1e-5 m²/m, filter matched", both(slipping("1e-5"), wheels("1e-5"))),
        ("started on the station (radius 0)", on_station),
        ("5 cm floor", spacing("0.05")),
        ("2 cm floor", spacing("0.02")),
        ("1 cm floor", spacing("0.01")),
        ("1 cm floor, started on the station", both(spacing("0.01"), on_station)),
        ("stations on cell corners", on_corners),
        ("stations on cell corners, wheel noise 1e-5", both(on_corners, wheels("1e-5"))),
        ("stations on cell corners, started on the station",
         both(on_corners, on_station)),
        ("stations on cell corners, started on the station, wheel noise 1e-5",
         both(on_corners, on_station, wheels("1e-5"))),
        ("stations on cell corners, started on the station, wheels slipping 1e-6 m²/m, "
         "filter matched", both(on_corners, on_station, slipping("1e-6"), wheels("1e-6"))),
    ]
    print("| fusion EKF, heading known | done | stop position p50 / p90 / worst (m) "
          "| worst stop heading (°) | cross-track p50 / worst (m) | worst time ratio |")
    print("| --- | ---: | --- | ---: | --- | ---: |")
    for i, (label, change) in enumerate(CASES):
        print(f"| {label} | " + row(*sweep(f"variant-{i}", change(SCENARIO))))
    sys.exit(0)

print("| estimator | start heading | done | stop position p50 / p90 / worst (m) "
      "| worst stop heading (°) | cross-track p50 / worst (m) | worst time ratio |")
print("| --- | --- | ---: | --- | ---: | --- | ---: |")
for e, (label, table) in enumerate(ESTIMATORS):
    for heading, line, start in HEADINGS:
        text = (SCENARIO.replace(EKF, table).replace(KNOWN_HEADING, line)
                .replace(KNOWN_START, start))
        print(f"| {label} | {heading} | " + row(*sweep(f"{e}-{heading}", text)))
