"""The persistent compilation cache seen from the command line: one command run twice,
each time in a new process, with one cache folder that starts empty.

The first run compiles and writes its programs to the folder; the second loads what
was written and compiles the rest (JAX never writes a program that calls back into
Python, e.g. a run-time check of a traced input). Commands (`--commands`):

- `fit`: `jaxcontact fit <creep file> --radius 5e-6` (the defaults: 4-arm Prony
  series on rings, the quality and uncertainty analysis);
- `run`: `jaxcontact run lc --n 64 --steps 21` (a coupled viscoelastic scene).

Usage::

    python benchmarks/cache_cli.py                       # both commands, this checkout
    python benchmarks/cache_cli.py --root /tmp/old --label before --variant before

Results: `benchmarks/results/cache_cli/<machine>.json` (`--variant`: a name after the
machine's; layout `results/SCHEMA.md`; per row: command, first and second wall time
[s], the cache entries the first run wrote, exit status).
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import header, write_results  # noqa: E402


CREEP = ROOT / "tests" / "data" / "fmt-jpk-cc_pr14-polymergel-2021.06.30.jpk-force"
COMMANDS = {
    "fit": ["fit", str(CREEP), "--radius", "5e-6", "--overwrite"],
    "run": ["run", "lc", "--n", "64", "--steps", "21", "--overwrite"],
}


def timed(argv, root, cache, out):
    """Wall time [s] and exit status of `python -m jaxcontact ARGV --out OUT` with the
    jaxcontact of `root` and the cache folder `cache`."""
    env = dict(os.environ, JAXCONTACT_CACHE_DIR=str(cache),
               PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH",
                                                                     "")]))
    env.pop("JAXCONTACT_NO_CACHE", None)
    start = time.perf_counter()
    command = [sys.executable, "-m", "jaxcontact", *argv, "--out", str(out)]
    proc = subprocess.run(command, env=env, capture_output=True, text=True, cwd=out)
    seconds = time.perf_counter() - start
    if proc.returncode not in (0, 1):  # 1: a fit flagged, still a result
        raise RuntimeError(f"{argv} failed:\n{proc.stderr[-3000:]}")
    return seconds, proc.returncode


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commands", nargs="+", default=list(COMMANDS),
                        choices=list(COMMANDS))
    parser.add_argument("--root", default=str(ROOT),
                        help="the checkout whose jaxcontact is measured")
    parser.add_argument("--label", default=None, help="a name for this tree")
    parser.add_argument("--variant", default=None,
                        help="the file's name after the machine's")
    parser.add_argument("--out", default=None, help="JSON path")
    args = parser.parse_args()
    rows = []
    for name in args.commands:
        with tempfile.TemporaryDirectory() as tmp:
            cache, out = Path(tmp) / "xla", Path(tmp) / "out"
            out.mkdir()
            first, code = timed(COMMANDS[name], args.root, cache, out)
            written = len(list(cache.glob("*"))) if cache.exists() else 0
            second, _ = timed(COMMANDS[name], args.root, cache, out)
        rows.append(dict(command="jaxcontact " + " ".join(COMMANDS[name]).replace(
            str(ROOT) + "/", ""), first_s=first, second_s=second,
            entries_written=written, exit=code))
        print(rows[-1], flush=True)
    result = header("cache_cli", variant=args.variant)
    result["settings"] = dict(commands=args.commands, root=args.root, label=args.label)
    result["rows"] = rows
    print(f"wrote {write_results(result, args.out)}")


if __name__ == "__main__":
    main()
