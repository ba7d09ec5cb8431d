#!/usr/bin/env python3
# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Record, then compare, the outputs of the user-facing commands: a refactor must leave them bit-identical.

    python tools/golden_outputs.py record DIR      # runs the commands through the `rotor-estimator` CLI
    python tools/golden_outputs.py compare A B     # exit 1 and name every difference

It calls only the console script, never a module path, so the same script runs before and after a
change of the package layout. What is compared: every command's stdout (JSON where the command has it),
the files the commands write (CSV, NPZ, JSON) byte for byte, and the messages of every bag written
(topic, log time and serialized bytes, read with `mcap`, so that a bag's container layout may change
while its content may not). Wall-clock figures (keys ending in `_s` of timing blocks, progress text) are
removed before comparing: they are the only outputs allowed to change.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BAG = str(ROOT / "bags" / "imbalance_impact")
RIG = str(ROOT / "rotor_estimator" / "rigs" / "miller_howard_2008.yaml")

# name -> arguments of `rotor-estimator`; {out} is this case's output folder.
CASES: dict[str, list[str]] = {
    "reproduce": ["reproduce", "miller-howard", "--runs", "2", "--json", "--no-progress"],
    "replay": ["replay", BAG, "--json", "--no-progress", "--out", "{out}/estimates", "--csv", "{out}/history.csv"],
    "identify_bag": ["identify", "--bag", BAG, "--json", "--no-progress"],
    "identify_simulated": ["identify", "--simulate", "imbalance+impact", "--method", "ekf+rts", "--json",
                           "--no-progress"],
    "plan": ["plan", "--json"],
    "simulate": ["simulate", "--out", "{out}/sim", "--no-progress"],
    "virtual_sensing": ["virtual-sensing", "--samples", "1024", "--json", "--no-progress",
                        "--estimates-out", "{out}/estimates.npz", "--out", "{out}/vs_bag"],
    "diagnose": ["diagnose", BAG, "--rig", RIG, "--json", "--no-progress"],
}

TIMING_KEY = re.compile(r"(^|_)(wall|elapsed|runtime|time_per|seconds_per|duration_wall)|_wall_s$|^timings?$")


def _strip_timings(value):
    if isinstance(value, dict):
        return {k: _strip_timings(v) for k, v in value.items() if not TIMING_KEY.search(k)}
    if isinstance(value, list):
        return [_strip_timings(v) for v in value]
    return value


def _bag_digest(folder: Path) -> list[str]:
    from mcap.reader import make_reader

    lines = []
    for path in sorted(folder.glob("*.mcap")):
        with open(path, "rb") as stream:
            for schema, channel, message in make_reader(stream).iter_messages(log_time_order=True):
                lines.append(f"{channel.topic} {schema.name if schema else '-'} {message.log_time} "
                             f"{hashlib.sha256(message.data).hexdigest()}")
    return lines


def record(target: Path) -> int:
    target.mkdir(parents=True, exist_ok=False)
    exe = shutil.which("rotor-estimator") or str(Path(sys.executable).parent / "rotor-estimator")
    env = dict(os.environ, TQDM_DISABLE="1", OMP_NUM_THREADS="1")
    failures = 0
    for name, args in CASES.items():
        out = target / name
        out.mkdir()
        argv = [exe] + [a.format(out=out) for a in args]
        run = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=ROOT)
        (out / "exit_code").write_text(f"{run.returncode}\n")
        text = run.stdout.replace(str(out), "{out}").replace(str(ROOT), "{root}")
        try:
            text = json.dumps(_strip_timings(json.loads(text)), indent=1, sort_keys=True)
        except json.JSONDecodeError:
            pass
        (out / "stdout").write_text(text)
        for bag in [p for p in out.iterdir() if p.is_dir()]:
            (out / f"{bag.name}.messages").write_text("\n".join(_bag_digest(bag)) + "\n")
            shutil.rmtree(bag)
        print(f"{name}: exit {run.returncode}", flush=True)
        if run.returncode != 0:
            print(run.stderr[-2000:], file=sys.stderr)
            failures += 1
    return 1 if failures else 0


def compare(a: Path, b: Path) -> int:
    files_a = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
    files_b = {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
    differences = [f"only in {a}: {p}" for p in sorted(files_a - files_b)]
    differences += [f"only in {b}: {p}" for p in sorted(files_b - files_a)]
    for rel in sorted(files_a & files_b):
        if (a / rel).read_bytes() != (b / rel).read_bytes():
            differences.append(f"differs: {rel}")
    for line in differences:
        print(line)
    print(f"{len(files_a & files_b)} files compared, {len(differences)} differences")
    return 1 if differences else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="action", required=True)
    sub.add_parser("record").add_argument("dir", type=Path)
    both = sub.add_parser("compare")
    both.add_argument("a", type=Path)
    both.add_argument("b", type=Path)
    args = parser.parse_args()
    return record(args.dir) if args.action == "record" else compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
