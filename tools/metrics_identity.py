"""Every shipped scene's metrics.json, digested, to show that a change to the code left them bit-identical.

    python tools/metrics_identity.py --out digests.json [--only NAME ...]
    python tools/metrics_identity.py --against digests.json [--only NAME ...]

Runs each shipped scene through `python -m bwr_twin.run --no-plots` (heavy_stack_and_reclaim
on the pile heavy_chevron_stack stacks, as its README row says) into a scratch folder, and
digests its metrics.json with each path to an input written from `<root>/`, so that two
checkouts of the same code give the same digests. `--against` compares with digests written
earlier and names each scene whose metrics differ, with the first keys that differ; the exit
status is 1 if any does.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
STACKED_FIRST = {"heavy_stack_and_reclaim": "heavy_chevron_stack"}  # a scene and the run whose pile it reclaims


def shipped() -> list[str]:
    names = sorted(p.stem for p in SCENES.glob("*.toml"))
    for later, first in STACKED_FIRST.items():  # the stacking before the reclaim of its pile
        names.remove(first)
        names.insert(names.index(later), first)
    return names


def canonical(text: str) -> dict:
    """metrics.json's object with every checkout's path to its inputs written `<root>/`."""
    return json.loads(re.sub(r'"[^"]*/(mjcf|scenes|out)/', r'"<root>/\1/', text))


def differences(old, new, where: str = "") -> list[str]:
    """The dotted keys at which two metrics objects differ."""
    if isinstance(old, dict) and isinstance(new, dict):
        found = []
        for key in sorted(set(old) | set(new)):
            if key not in old or key not in new:
                found.append(f"{where}{key} ({'added' if key not in old else 'removed'})")
            else:
                found += differences(old[key], new[key], f"{where}{key}.")
        return found
    return [] if old == new else [f"{where.rstrip('.')}: {str(old)[:60]} -> {str(new)[:60]}"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--out", type=Path, help="write the digests here")
    what.add_argument("--against", type=Path, help="compare with the digests written here")
    parser.add_argument("--only", nargs="+", help="these scenes only")
    args = parser.parse_args()
    names = [n for n in shipped() if not args.only or n in args.only]
    found: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as scratch:
        for name in names:
            out = Path(scratch) / name
            command = [sys.executable, "-m", "bwr_twin.run", name, "--out", str(out), "--no-plots"]
            if name in STACKED_FIRST:
                command += ["--pile", str(Path(scratch) / STACKED_FIRST[name] / "pile.npz")]
            started = time.perf_counter()
            done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
            if done.returncode != 0:
                print(f"{name}: exit {done.returncode}: {done.stderr.strip()[-300:]}")
                return 1
            metrics = canonical((out / "metrics.json").read_text())
            digest = hashlib.sha256(json.dumps(metrics, sort_keys=True).encode()).hexdigest()
            found[name] = {"sha256": digest, "metrics": metrics}
            print(f"{name:36s} {digest[:16]}  {time.perf_counter() - started:6.1f} s", flush=True)
    if args.out is not None:
        args.out.write_text(json.dumps(found, indent=1, sort_keys=True))
        return 0
    before = json.loads(args.against.read_text())
    for name, then in before.items():  # digests written before paths were made canonical
        then["metrics"] = canonical(json.dumps(then["metrics"]))
        then["sha256"] = hashlib.sha256(json.dumps(then["metrics"], sort_keys=True).encode()).hexdigest()
    changed, compared = 0, 0
    for name, now in found.items():
        if name not in before:
            print(f"{name}: not in {args.against}, new")
            continue
        compared += 1
        if before[name]["sha256"] != now["sha256"]:
            changed += 1
            keys = differences(before[name]["metrics"], now["metrics"])
            print(f"{name}: differs at {len(keys)} keys: " + "; ".join(keys[:6]))
    print(f"{compared - changed} of {compared} scenes' metrics.json identical ({len(found) - compared} new)")
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
