"""The runtime model's held-out error on a rig's own animation as random poses are added
(docs/experiments.md, "How many poses, and which"): what `export_examples.py --poses auto` buys,
replayed from a pool exported once:

    python3 tools/experiments/pose_count.py POOL --rrskin target/release/rrskin \\
        [--start 40] [--round 20] [--budget 120] [--json]

POOL: an example-set folder (data/README.md) whose training poses are pose 0 (the rest pose)
then random range-of-motion poses (make_black_boxes.py or export_examples.py with a large
--poses), and whose test poses are the rig's own animation. From the rest pose and the first
--start random poses, --round more a step up to --budget, `rrskin train` scores the runtime
model on the held-out animation at every count. One line per count (one JSON object with
--json).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

FILES = ("rest_vertices.npy", "faces.npy", "bone_parents.npy", "bone_names.json", "skin_weights.npy")


def load(pool):
    split = np.load(os.path.join(pool, "split.npy"))
    return {
        "transforms": np.load(os.path.join(pool, "pose_transforms.npy")),
        "vertices": np.load(os.path.join(pool, "pose_vertices.npy")),
        "train": [i for i in range(len(split)) if split[i] == 0],
        "test": [i for i in range(len(split)) if split[i] == 1],
    }


def write_subset(pool, data, chosen, out):
    """The pool's rest pose, `chosen` training poses and every test pose, as a set in `out`."""
    os.makedirs(out, exist_ok=True)
    for name in FILES:
        src = os.path.join(pool, name)
        if os.path.exists(src):
            with open(src, "rb") as f, open(os.path.join(out, name), "wb") as g:
                g.write(f.read())
    rows = [data["train"][0]] + list(chosen) + data["test"]
    np.save(os.path.join(out, "pose_transforms.npy"), data["transforms"][rows])
    np.save(os.path.join(out, "pose_vertices.npy"), data["vertices"][rows])
    split = [0] * (1 + len(chosen)) + [1] * len(data["test"])
    np.save(os.path.join(out, "split.npy"), np.array(split, dtype=np.int32))


def rrskin(binary, args):
    run = subprocess.run([binary] + args + ["--json"], capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"error: rrskin {' '.join(args)}: {run.stderr.strip()}")
    return json.loads(run.stdout)


def play(pool, data, args, work):
    rows = []
    for count in range(args.start, args.budget + 1, args.round):
        chosen = data["train"][1:1 + count]
        if len(chosen) < count:
            break
        subset = os.path.join(work, "set")
        write_subset(pool, data, chosen, subset)
        report = rrskin(args.rrskin, ["train", subset, "-o", os.path.join(work, "m.rrs")])
        r = {"poses": count + 1, "rr_test": report["rr_reduced"]["test"],
             "ssd_test": report["ssd"]["test"],
             "clamped": (report.get("proxy_correctives") or {}).get("clamped")}
        rows.append(r)
        if not args.json:
            print(f"{r['poses']:>4} poses: runtime {r['rr_test']:.2f} %, SSD {r['ssd_test']:.2f} %, "
                  f"ratio {r['rr_test'] / r['ssd_test']:.3f}, proxy correctives clamped: "
                  f"{r['clamped']}", flush=True)
    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("pool")
    p.add_argument("--rrskin", required=True)
    p.add_argument("--start", type=int, default=40)
    p.add_argument("--round", type=int, default=20)
    p.add_argument("--budget", type=int, default=120)
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    data = load(args.pool)
    with tempfile.TemporaryDirectory() as work:
        rows = play(args.pool, data, args, work)
    if args.json:
        print(json.dumps({"pool": args.pool, "rows": rows}))


if __name__ == "__main__":
    main()
