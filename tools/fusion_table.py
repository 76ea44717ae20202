#!/usr/bin/env python3
"""The fusion filters side by side (issue 32, item 3): the tables of
docs/fusion.md, "The three filters together".

    python3 tools/fusion_table.py [RUNS]   # from the repository root; default 32

1. The template's defaults: `firmware-sim show figure_eight_rfid_fusion_ekf`
   run as it is and with only `filter` switched; max / mean / rms position
   error after its 100 s transient, m.
2. The grid: paper 001's RFID figure-eight, a circle (2 m radius, 0.1 m/s)
   and a line (0.1 m/s), each on 10, 20 and 30 cm tag floors, the plant's
   wheels slipping with a travel variance of 1e-6, 1e-4 and 1e-2 m²/m
   (`[plant.wheels]`), each filter's `wheel_variance_per_m` matched to it
   and 10x off either way; a sweep of RUNS starts within 1 m of the
   reference's start, any heading, the tag lattice offset anywhere in a
   cell. Each cell is the median over the runs of each run's max position
   error after the 100 s transient, m; paper 001's observer (5) on the
   same runs is the floor every filter must beat.

The goals of issue 32 are checked at the end and printed as counts.
The sweeps' files go to target/fusion-table/. About 20 minutes on 2
cores at 32 runs, about 7 at 8.

    python3 tools/fusion_table.py starts [FILTER ...] [--seed N] [--cases I,J,...]
    # default: particle_filter, the filter's default particle_seed, every case

3. The starts table of docs/fusion.md ("The particle filter at the
   template's defaults"): the template on the RFID figure-eight with
   `filter` set, over 8 starts (`[initial]` moved by k µm in x and 10 k µrad
   in heading, k = 0…7, as the fusion tests' ensembles move it), for the
   template's noise (1e-3, 3e-5, 2e-7 m²/m on exact wheels; 1e-3 on 20 and
   30 cm floors) and for wheels that slip (`[plant.wheels]` 1e-6 and 1e-4
   m²/m, measurement seed k + 1) with the filter matched and 10x off
   either way. Each row: the median and worst of the runs' max errors and
   the median of their mean errors after 100 s, m. About 2 minutes a
   filter on 2 cores (single runs, two at a time). `--seed N` sets
   `particle_seed = N` (the other particle draws of the docs: N = (k << 32) + 1);
   `--cases` runs only those rows of START_CASES (0-based).
"""

import concurrent.futures
import json
import os
import pathlib
import re
import shutil
import statistics
import subprocess
import sys

STARTS = len(sys.argv) > 1 and sys.argv[1] == "starts"
ARGS = sys.argv[2:]
PARTICLE_SEED = None
CASES = None
if STARTS:
    for flag in ("--seed", "--cases"):
        if flag in ARGS:
            i = ARGS.index(flag)
            value = ARGS[i + 1]
            del ARGS[i:i + 2]
            if flag == "--seed":
                PARTICLE_SEED = int(value, 0)
            else:
                CASES = [int(c) for c in value.split(",")]
RUNS = int(sys.argv[1]) if len(sys.argv) > 1 and not STARTS else 32
ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "target" / "fusion-table"
OUT.mkdir(parents=True, exist_ok=True)
# Built once and copied, so that every run of a table comes from the same
# binary even if the sources change while it runs.
subprocess.run(["cargo", "build", "--release", "-q", "-p", "firmware-sim"], cwd=ROOT, check=True)
_TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
shutil.copy2(_TARGET / "release" / "firmware-sim", OUT / "firmware-sim")
SIM = [str(OUT / "firmware-sim")]

TEMPLATE = subprocess.run(SIM + ["show", "figure_eight_rfid_fusion_ekf"], cwd=ROOT,
                          check=True, capture_output=True, text=True).stdout
FILTERS = [("EKF", "ekf"), ("UKF", "ukf"), ("particle filter", "particle_filter")]
FILTER_LINE = 'filter = "ekf"'
WHEEL_LINE = re.compile(r"^wheel_variance_per_m = .*$", re.M)
PLANT = '[plant]\nkind = "unicycle"\n'
SPACING = "spacing_m = 0.1\n"
for needed in (FILTER_LINE, PLANT, SPACING, "[reference]\n", "[initial]\n"):
    assert needed in TEMPLATE, f"the template no longer has {needed!r}"
assert WHEEL_LINE.search(TEMPLATE), "the template no longer sets wheel_variance_per_m"


def run(name, text):
    """One run of `text`: its summary."""
    path = OUT / f"{name}.toml"
    path.write_text(text)
    subprocess.run(SIM + ["run", str(path), "--no-plot", "--out", str(OUT / name)],
                   cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return json.loads((OUT / name / "summary.json").read_text())


def sweep(name, text):
    """A sweep of `text`: its summary's median of the per-run max errors, m."""
    path = OUT / f"{name}.toml"
    path.write_text(text)
    subprocess.run(SIM + ["sweep", str(path), "--runs", str(RUNS), "--no-plot",
                          "--out", str(OUT / name)],
                   cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    s = json.loads((OUT / name / "summary.json").read_text())
    return s["max_error_m"]["p50"]


def with_filter(text, kind, wheel_variance=None):
    text = text.replace(FILTER_LINE, f'filter = "{kind}"')
    if wheel_variance is not None:
        text = WHEEL_LINE.sub(f"wheel_variance_per_m = {wheel_variance:g}", text)
    return text


def without_filter(text):
    """Paper 001's observer (5): the template without its [estimator.fusion] table."""
    start = text.index("[estimator.fusion]")
    end = text.index("\n[", start + 1) + 1
    return text[:start] + text[end:]


def with_reference(text, reference):
    start = text.index("[reference]\n")
    end = text.index("[initial]\n")
    return text[:start] + reference + "\n" + text[end:]


# 3. The starts table (a filter's single runs from 8 starts).
START_CASES = [
    # (filter's wheel_variance_per_m, floor spacing m, plant slip m²/m)
    (1e-3, 0.1, 0.0), (3e-5, 0.1, 0.0), (2e-7, 0.1, 0.0), (1e-3, 0.2, 0.0), (1e-3, 0.3, 0.0),
    (1e-6, 0.1, 1e-6), (1e-5, 0.1, 1e-6), (1e-7, 0.1, 1e-6),
    (1e-4, 0.1, 1e-4), (1e-3, 0.1, 1e-4), (1e-5, 0.1, 1e-4),
]
START_COUNT = 8
HEADING_LINE = "heading_rad = 4.71238898038469"
X_LINE = "x_m = 0.0\n"


def start_text(kind, wheel_variance, spacing, slip, k):
    """The template with `kind`, its noise, floor, plant slip and start k."""
    assert HEADING_LINE in TEMPLATE and X_LINE in TEMPLATE, "the template's [initial] changed"
    text = with_filter(TEMPLATE, kind, wheel_variance)
    text = text.replace(SPACING, f"spacing_m = {spacing:g}\n")
    text = text.replace(X_LINE, f"x_m = {k * 1e-6!r}\n", 1)
    text = text.replace(HEADING_LINE, f"heading_rad = {4.71238898038469 + k * 1e-5!r}", 1)
    if PARTICLE_SEED is not None:
        text = text.replace("[estimator.fusion]", f"[estimator.fusion]\nparticle_seed = {PARTICLE_SEED}", 1)
    if slip:
        text = text.replace(PLANT, PLANT + f"\n[plant.wheels]\ntravel_variance_m2_per_m = {slip:g}\n")
        text += f"\n[measurement]\nseed = {k + 1}\n"
    return text


def starts_table(kinds):
    binary = SIM[0]

    def one(job):
        kind, wheel_variance, spacing, slip, k = job
        name = f"starts-{kind}-{wheel_variance:g}-{spacing:g}-{slip:g}-{k}"
        path = OUT / f"{name}.toml"
        path.write_text(start_text(*job))
        subprocess.run([binary, "run", str(path), "--no-plot", "--out", str(OUT / name)],
                       cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
        s = json.loads((OUT / name / "summary.json").read_text())
        # A run.csv is about 20 MB and only the summary is read.
        (OUT / name / "run.csv").unlink(missing_ok=True)
        return job, s["max_error_m"], s["mean_error_m"]

    cases = START_CASES if CASES is None else [START_CASES[i] for i in CASES]
    jobs = [(kind, *case, k) for kind in kinds for case in cases for k in range(START_COUNT)]
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        results = list(pool.map(one, jobs))
    print("| filter | wheel_variance_per_m | floor (m) | plant slip (m²/m) "
          "| median max | worst max | median mean |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for kind in kinds:
        for case in cases:
            runs = [(m, mean) for job, m, mean in results if job[:4] == (kind, *case)]
            maxima = [m for m, _ in runs]
            means = [mean for _, mean in runs]
            print(f"| {kind} | {case[0]:g} | {case[1]:g} | {case[2]:g} "
                  f"| {statistics.median(maxima):.4f} | {max(maxima):.4f} "
                  f"| {statistics.median(means):.4f} |")


def grid():
    # 1. The template's defaults, single runs.
    print("| filter (template defaults) | max (m) | mean (m) | rms (m) |")
    print("| --- | ---: | ---: | ---: |")
    for label, kind in FILTERS:
        s = run(f"template-{kind}", with_filter(TEMPLATE, kind))
        print(f"| {label} | {s['max_error_m']:.4f} | {s['mean_error_m']:.4f} | {s['rms_error_m']:.4f} |")
    s = run("template-observer", without_filter(TEMPLATE))
    print(f"| paper 001's observer (5) | {s['max_error_m']:.4f} | {s['mean_error_m']:.4f} "
          f"| {s['rms_error_m']:.4f} |")
    print()

    # 2. The grid.
    CURVES = [
        ("figure-eight", None),
        ("circle", '[reference]\nkind = "circle"\ncenter_m = [0.0, 0.0]\nradius_m = 2.0\n'
                   'rate_rad_s = 0.05\nphase_rad = 0.0\n'),
        ("line", '[reference]\nkind = "line"\nstart_m = [0.0, 0.0]\nheading_rad = 0.5\n'
                 'speed_m_s = 0.1\n'),
    ]
    SWEEP = ('\n[sweep]\nstart_radius_m = [0.0, 1.0]\ninitial_heading = "any"\n'
             'tag_offset = true\n')
    FLOORS = [0.1, 0.2, 0.3]
    NOISES = [1e-6, 1e-4, 1e-2]
    TUNINGS = [("matched", 1.0), ("×10", 10.0), ("÷10", 0.1)]

    header = "| curve | floor (m) | wheels (m²/m) | observer (5) |"
    rule = "| --- | ---: | ---: | ---: |"
    for label, _ in FILTERS:
        for tuning, _ in TUNINGS:
            header += f" {label} {tuning} |"
            rule += " ---: |"
    print(header)
    print(rule)
    checks = {"within 1.5x of the EKF (matched)": [0, 0], "within 2x of its matched (mis-tuned)": [0, 0],
              "no worse than observer (5)": [0, 0]}
    for curve, reference in CURVES:
        base = TEMPLATE if reference is None else with_reference(TEMPLATE, reference)
        base += SWEEP
        for floor in FLOORS:
            for noise in NOISES:
                text = (base.replace(SPACING, f"spacing_m = {floor:g}\n")
                        .replace(PLANT, PLANT + f"\n[plant.wheels]\ntravel_variance_m2_per_m = {noise:g}\n"))
                name = f"{curve}-{floor:g}-{noise:g}"
                observer = sweep(f"{name}-observer", without_filter(text))
                row = f"| {curve} | {floor:g} | {noise:g} | {observer:.4f} |"
                figures = {}
                for _, kind in FILTERS:
                    for tuning, factor in TUNINGS:
                        m = sweep(f"{name}-{kind}-{tuning}", with_filter(text, kind, noise * factor))
                        figures[(kind, tuning)] = m
                        row += f" {m:.4f} |"
                print(row, flush=True)
                ekf = figures[("ekf", "matched")]
                for _, kind in FILTERS:
                    matched = figures[(kind, "matched")]
                    if kind != "ekf":
                        c = checks["within 1.5x of the EKF (matched)"]
                        c[0] += matched <= 1.5 * ekf
                        c[1] += 1
                    for tuning, _ in TUNINGS[1:]:
                        c = checks["within 2x of its matched (mis-tuned)"]
                        c[0] += figures[(kind, tuning)] <= 2.0 * matched
                        c[1] += 1
                    for tuning, _ in TUNINGS:
                        c = checks["no worse than observer (5)"]
                        c[0] += figures[(kind, tuning)] <= observer
                        c[1] += 1
    print()
    for goal, (met, cases) in checks.items():
        print(f"- {goal}: {met} of {cases} cases")


if STARTS:
    starts_table(ARGS or ["particle_filter"])
else:
    grid()
