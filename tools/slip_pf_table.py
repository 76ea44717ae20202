#!/usr/bin/env python3
"""Rows of docs/paper-004.md's "Issue 17" table from `firmware-sim slip` runs.

Runs the release simulator for seeds FROM..TO on one scenario, once with the
EKF and once with the particle filter (N particles), and prints: diverged
count, mean over seeds of the position RMS per window (tracking[]), the worst
seed's ratio of the particle filter's RMS to the EKF's in any window of the
same seed, and the mean over seeds of p-hat during the slip
(slip_estimate[0].mean_slip_estimate). Diverged seeds are left out of the
means and the ratio (and counted).

  cargo build --release -p firmware-sim
  python3 tools/slip_pf_table.py paper_004_torque --particles 100 --seeds 1 20

Extra arguments after `--` go to the particle-filter runs only (e.g. a
scenario file path instead of the name, or `--particles`).
"""
import argparse
import json
import pathlib
import subprocess
import sys
import tempfile


def run(binary, scenario, estimator, seed, out, extra):
    cmd = [binary, "slip", scenario, "--estimator", estimator, "--seed", str(seed),
           "--no-plot", "--json", "--out", str(out)] + extra
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return json.loads((out / "summary.json").read_text())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario")
    ap.add_argument("--particles", type=int, default=100)
    ap.add_argument("--seeds", type=int, nargs=2, default=[1, 20])
    ap.add_argument("--binary", default="target/release/firmware-sim")
    ap.add_argument("rest", nargs="*", help="extra particle-filter arguments")
    a = ap.parse_args()
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="slip_pf_"))
    rows = {"ekf": [], "pf": []}
    diverged = {"ekf": 0, "pf": 0}
    worst = 0.0
    for seed in range(a.seeds[0], a.seeds[1] + 1):
        ekf = run(a.binary, a.scenario, "ekf", seed, tmp / f"ekf{seed}", [])
        pf = run(a.binary, a.scenario, "particle_filter", seed, tmp / f"pf{seed}",
                 ["--particles", str(a.particles)] + a.rest)
        for name, s in (("ekf", ekf), ("pf", pf)):
            if s["diverged"]:
                diverged[name] += 1
            else:
                rms = [w["position_error_rms_m"] for w in s["tracking"]]
                rows[name].append((rms, s["slip_estimate"][0]["mean_slip_estimate"]))
        if not (ekf["diverged"] or pf["diverged"]):
            for e, p in zip(ekf["tracking"], pf["tracking"]):
                worst = max(worst, p["position_error_rms_m"] / e["position_error_rms_m"])
    for name in ("ekf", "pf"):
        r = rows[name]
        if not r:
            print(f"{name}: diverged {diverged[name]}, no finite run")
            continue
        windows = len(r[0][0])
        mean_rms = [sum(x[0][i] for x in r) / len(r) for i in range(windows)]
        p_hat = sum(x[1] for x in r) / len(r)
        ratio = "1" if name == "ekf" else f"{worst:.2f}"
        print(f"{a.scenario} {name} N={a.particles} seeds {a.seeds[0]}-{a.seeds[1]}: "
              f"diverged {diverged[name]} | RMS "
              + " / ".join(f"{m:.3f}" for m in mean_rms)
              + f" | worst ratio {ratio} | p_hat {p_hat:.3f}")


if __name__ == "__main__":
    sys.exit(main())
