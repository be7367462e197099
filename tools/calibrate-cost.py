#!/usr/bin/env python3
"""Calibrates the cost model (src/cost.rs) against measurement on this machine.

    tools/calibrate-cost.py MODEL.rrs... [--rrskin target/release/rrskin] [--characters 256]

For each model: `rrskin info --json` gives every pass's predicted work a character (bytes,
multiply-adds, special operations), `rrskin bench --json` the Vulkan passes' measured times
(RR with recomputed normals, with transformed normals, and the engine baseline), and `rrskin
bench --palette --json` the CPU palette's. The rates (ns per unit of work) are fitted by
non-negative least squares on relative errors, one set for the Vulkan passes and one for the
palette. A Vulkan pass is fitted as its time over the engine baseline's in the same run (these
machines are noisy from run to run, not within one); the rates' scale is set by the engine
baseline's mean time. Then each model's predicted against measured ratio to the engine baseline
and palette µs are printed, with the error. Paste the rates into `LAVAPIPE` in src/cost.rs.

    tools/calibrate-cost.py --check MODEL.rrs...

checks the rates in src/cost.rs (as `rrskin info --json` applies them) on models, fitting
nothing: for models the fit did not see. `--cache DIR` keeps the measurements (bench and
palette JSON per model) and reuses them, so that a change to the work counts is refitted at
once.
"""
import argparse
import itertools
import json
import os
import subprocess
import sys

import numpy as np

# bench's per-pass timings, and the cost model's passes each holds.
BENCH_PASSES = {
    "predict_ms": ["predict", "corrective weights"],
    "blend_ms": ["product"],
    "proxy_correctives_ms": ["proxy correctives"],
    "skin_ms": ["skinning"],
    "normals_ms": ["normals"],
}
UNITS = ("groups", "bytes", "loads", "gathers", "streams", "madds", "specials")


def run(rrskin, *args):
    out = subprocess.run([rrskin, *args], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def work(passes, names):
    rows = [p for p in passes if p["pass"] in names]
    return np.array([sum(p[u] for p in rows) for u in UNITS])


def nnls(a, b):
    """Least squares with x >= 0, by trying every set of free variables (a few unknowns)."""
    best = (np.inf, np.zeros(a.shape[1]))
    for k in range(1, a.shape[1] + 1):
        for free in itertools.combinations(range(a.shape[1]), k):
            x = np.zeros(a.shape[1])
            x[list(free)] = np.linalg.lstsq(a[:, free], b, rcond=None)[0]
            r = np.sum((a @ x - b) ** 2)
            if (x >= 0).all() and r < best[0]:
                best = (r, x)
    return best[1]


def fit_frame(results, iterations=8):
    """Rates r with r.w_pass = rho r.w_engine for every pass of every model, relative errors
    (reweighted by the last iterate), scaled so that the engine baseline's mean is measured."""
    rows = [(w, rho, res["engine"][0]) for res in results for w, rho in res["rows"]]
    engines = np.array([res["engine"][0] for res in results])
    measured = np.mean([res["engine"][1] for res in results])
    r = np.ones(len(UNITS))
    for _ in range(iterations):
        a = [(w - rho * e) / max(rho * (e @ r), 1e-12) for w, rho, e in rows]
        a.append(100.0 * engines.mean(axis=0) / measured)
        b = np.zeros(len(a))
        b[-1] = 100.0
        r = nnls(np.array(a), b)
    return r


def measured(rrskin, cache, name, *args):
    """`rrskin ARGS --json`, or its output saved under `cache` (a folder, or None) as NAME."""
    path = cache and os.path.join(cache, name)
    if path and os.path.exists(path):
        with open(path) as f:
            return json.load(f)
    out = run(rrskin, *args)
    if path:
        os.makedirs(cache, exist_ok=True)
        with open(path, "w") as f:
            json.dump(out, f)
    return out


def measure(rrskin, model, characters, frames, cache):
    info = run(rrskin, "info", model, "--json")["cost"]["targets"]
    common = ["--characters", str(characters), "--frames", str(frames), "--json"]
    stem = os.path.basename(model)
    bench = measured(rrskin, cache, f"{stem}.bench.json", "bench", model, *common)
    palette = measured(rrskin, cache, f"{stem}.palette.json", "bench", model, "--palette", *common)
    per_char = 1e6 / characters  # ms a frame to ns a character
    engine = info["transformed_normals"]["engine"]
    engine = (np.array([engine[u] for u in UNITS]), bench["engine_passes"]["skin_ms"] * per_char)
    rows, names = [], []  # (work, its measured time over the engine baseline's)
    for target, key in (("recomputed_normals", "rr_passes"), ("transformed_normals", "rr_transformed_passes")):
        for name, passes in BENCH_PASSES.items():
            w = work(info[target]["passes"], passes)
            t = bench[key][name] * per_char
            if w.any() and t > 0:
                rows.append((w, t / engine[1]))
                names.append(f"{target[:4]}:{name}")
    return {
        "model": model,
        "rows": rows,
        "names": names,
        "engine": engine,
        "info": info,
        "rr_vs_engine": bench["rr_vs_engine"],
        "rr_over_engine": bench["rr_ms"] / bench["engine_ms"],
        "palette_work": sum((work(info["palette"]["passes"], [p["pass"]]) for p in info["palette"]["passes"]), np.zeros(len(UNITS))),
        "palette_ns": palette["palette_us"] * 1e3,
        "palette_us_threads": palette["palette_us_threads"],
    }


def predicted_ratio(info, target, rates):
    ns = sum(work([p], [p["pass"]]) @ rates for p in info[target]["passes"])
    e = info[target]["engine"]
    return ns / (np.array([e[u] for u in UNITS]) @ rates)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("models", nargs="+")
    ap.add_argument("--rrskin", default="target/release/rrskin")
    ap.add_argument("--characters", type=int, default=256)
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--check", action="store_true", help="predict with the rates the binary has; fit nothing")
    ap.add_argument("--passes", action="store_true", help="also print each pass's measured and predicted time over the engine baseline's")
    ap.add_argument("--cache", help="a folder: keep each model's measurements there, and reuse those kept (to refit after changing the work counts, without measuring again)")
    args = ap.parse_args()
    results = []
    for m in args.models:
        print(f"measuring {m}", file=sys.stderr)
        results.append(measure(args.rrskin, m, args.characters, args.frames, args.cache))
    if args.check:
        report(results, None, None)
        return
    frame = fit_frame(results)
    a = np.array([r["palette_work"] / r["palette_ns"] for r in results])
    palette = nnls(a, np.ones(len(results)))
    print("frame rates (ns per group, byte, load, gather, stream, madd, special):", ", ".join(f"{x:.6g}" for x in frame))
    print("palette rates (ns per group, byte, load, gather, stream, madd, special):", ", ".join(f"{x:.6g}" for x in palette))
    print()
    report(results, frame, palette)
    if args.passes:
        for r in results:
            e = r["engine"][0] @ frame
            print(r["model"], " ".join(f"{n} {rho:.3f}/{w @ frame / e:.3f}" for n, (w, rho) in zip(r["names"], r["rows"])))


def report(results, frame, palette):
    """Each model's predicted against measured ratios and palette µs (the binary's own
    predictions where `frame` and `palette` are None)."""
    print("| model | RR / engine measured (paired) | predicted | error | RR recomputed / engine measured | predicted | error | palette us measured | predicted | error |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    worst = 0.0
    for r in results:
        if frame is None:
            t, c = (r["info"][k]["ratio"] for k in ("transformed_normals", "recomputed_normals"))
            p = r["info"]["palette"]["us"]
        else:
            t = predicted_ratio(r["info"], "transformed_normals", frame)
            c = predicted_ratio(r["info"], "recomputed_normals", frame)
            p = r["palette_work"] @ palette * 1e-3
        m = r["palette_ns"] * 1e-3
        errors = [t / r["rr_vs_engine"] - 1, c / r["rr_over_engine"] - 1, p / m - 1]
        worst = max(worst, *map(abs, errors))
        print(f"| {r['model']} | {r['rr_vs_engine']:.3f} | {t:.3f} | {100 * errors[0]:+.1f} % "
              f"| {r['rr_over_engine']:.3f} | {c:.3f} | {100 * errors[1]:+.1f} % "
              f"| {m:.2f} | {p:.2f} | {100 * errors[2]:+.1f} % |")
    print(f"\nlargest error: {100 * worst:.1f} %")


if __name__ == "__main__":
    main()
