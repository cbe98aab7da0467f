"""What the benchmark scripts share: the Hertz sphere, machine and version records, the
FFT floor of an iteration, and the one layout of a results file (`results/SCHEMA.md`):
`header` starts a record, `write_results` checks it and writes
`results/<benchmark>/<machine>[_<variant>].json`.

Imports nothing from another benchmark, and jax only inside the functions (so that a
script that runs its cases in subprocesses, `run.py`, stays light in the parent).
"""

from __future__ import annotations

import datetime
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path


HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results"

# The rigid sphere of the Hertz, Cattaneo-Mindlin and Spence benchmarks (SI units).
RADIUS = 10e-3  # m
FORCE = 0.15  # N
SHEAR_MODULUS = 1e6  # Pa
POISSON = 0.3


# ---- Machine and versions ---------------------------------------------------------


def _cpu_model() -> str:
    name = platform.processor()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return name


def _git(*args) -> str | None:
    try:
        out = subprocess.run(
            ["git", "-C", str(ROOT), *args], capture_output=True, text=True, timeout=10
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def _jaxlib_version():
    try:
        import jaxlib

        return jaxlib.__version__
    except Exception:  # pragma: no cover
        return None


def machine_info() -> dict:
    import jax
    import numpy as np

    dev = jax.devices()[0]
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = os.cpu_count()
    return {
        "platform": platform.platform(),
        "processor": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "cpu_count_usable": usable,
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": getattr(jax.lib, "__version__", None) or _jaxlib_version(),
        "numpy": np.__version__,
        "device": str(dev),
        "device_kind": getattr(dev, "device_kind", None),
        "backend": jax.default_backend(),
    }


def library_info() -> dict:
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import jaxcontact as jc

    dirty = _git("status", "--porcelain", "--", "jaxcontact")
    return {
        "jaxcontact": jc.__version__,
        "path": str(Path(jc.__file__).resolve().parent),
        "git_commit": _git("rev-parse", "HEAD"),
        "jaxcontact_dirty": None if dirty is None else bool(dirty),
    }


def _loadavg():
    try:
        return list(os.getloadavg())
    except OSError:
        return None


def machine_name(machine: dict) -> str:
    """A short name of a machine for file names: the GPU's kind on a GPU (`"h200"`),
    else the CPU's vendor and family (`"intel_xeon"`, `"amd_epyc"`); `"unknown"`
    where the record names neither."""
    backend = machine.get("backend")
    kind = machine.get("device_kind")
    if backend in ("gpu", "cuda", "rocm", "tpu") and kind and kind != "unknown":
        words = [w for w in kind.lower().split() if w not in ("nvidia", "amd", "tesla")]
    else:
        text = str(machine.get("processor") or "")
        for junk in ("(R)", "(TM)", "(r)", "(tm)", "CPU", "Processor"):
            text = text.replace(junk, " ")
        words = text.lower().split("@")[0].split()[:2]
    name = "_".join("".join(c for c in w if c.isalnum()) for w in words).strip("_")
    return name if name and name not in ("unknown", "x8664") else "unknown"


def header(benchmark: str, argv=None, variant: str | None = None) -> dict:
    """The fields every results file starts with (`results/SCHEMA.md`): benchmark,
    variant, date, command, machine (with its `name`), commit, dirty, versions. The
    caller adds `settings` and `rows` (and, optionally, `summary` and `notes`) and
    hands the record to `write_results`."""
    info = machine_info()
    lib = library_info()
    versions = {key: info.pop(key) for key in ("python", "jax", "jaxlib", "numpy")}
    versions["jaxcontact"] = lib["jaxcontact"]
    info["load_average"] = _loadavg()
    info = {"name": machine_name(info), **info}
    return {
        "benchmark": benchmark,
        "variant": variant,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "command": " ".join(
            [Path(sys.argv[0]).name, *(sys.argv[1:] if argv is None else argv)]),
        "machine": info,
        "commit": lib["git_commit"],
        "dirty": lib["jaxcontact_dirty"],
        "versions": versions,
    }


def results_path(benchmark: str, variant: str | None = None,
                 machine: str | None = None) -> Path:
    """`benchmarks/results/<benchmark>/<machine>[_<variant>].json`; `machine`
    defaults to this machine's name (`machine_name`, which imports jax)."""
    if machine is None:
        machine = machine_name(machine_info())
    stem = machine + (f"_{variant}" if variant else "")
    return RESULTS / benchmark / f"{stem}.json"


# The keys of a results file and their types (`results/SCHEMA.md`); a value a
# converted old run did not record is the string "unknown".
SCHEMA = {
    "benchmark": str,
    "variant": (str, type(None)),
    "date": str,
    "command": str,
    "machine": dict,
    "commit": (str, type(None)),
    "dirty": (bool, str, type(None)),
    "versions": dict,
    "settings": dict,
    "rows": list,
}
MACHINE_KEYS = ("name", "platform", "processor", "cpu_count", "device_kind", "backend")
VERSION_KEYS = ("python", "jax", "jaxlib", "numpy", "jaxcontact")


def schema_problems(record) -> list[str]:
    """What in `record` breaks the layout of `results/SCHEMA.md` (empty if nothing):
    a missing key, a value of the wrong type, a row that is not an object."""
    if not isinstance(record, dict):
        return [f"a results record is a JSON object, not {type(record).__name__}"]
    problems = []
    for key, kind in SCHEMA.items():
        if key not in record:
            problems.append(f"missing key {key!r}")
        elif not isinstance(record[key], kind):
            problems.append(f"{key!r} is {type(record[key]).__name__}")
    for block, keys in (("machine", MACHINE_KEYS), ("versions", VERSION_KEYS)):
        if isinstance(record.get(block), dict):
            problems += [f"missing {block}.{k}" for k in keys if k not in record[block]]
    if isinstance(record.get("machine"), dict) and not isinstance(
            record["machine"].get("name"), str):
        problems.append("machine.name is not a string")
    if isinstance(record.get("rows"), list):
        if not record["rows"]:
            problems.append("'rows' is empty")
        bad = [i for i, row in enumerate(record["rows"]) if not isinstance(row, dict)]
        if bad:
            problems.append(f"rows {bad[:5]} are not objects")
    if "summary" in record and not isinstance(record["summary"], dict):
        problems.append("'summary' is not an object")
    if "notes" in record and not (isinstance(record["notes"], list) and all(
            isinstance(n, str) for n in record["notes"])):
        problems.append("'notes' is not a list of strings")
    return problems


def _jsonable(value):
    """NumPy and JAX scalars and arrays as JSON numbers and lists."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (set, tuple)):
        return list(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable: {value!r}")


def write_results(record: dict, out=None) -> Path:
    """Check `record` against `results/SCHEMA.md` and write it to `out` (default
    `results_path(benchmark, variant, machine name)`); return the path."""
    problems = schema_problems(record)
    if problems:
        raise ValueError("results record breaks results/SCHEMA.md: "
                         + "; ".join(problems))
    path = Path(out) if out else results_path(
        record["benchmark"], record["variant"], record["machine"]["name"])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=1, default=_jsonable) + "\n")
    return path


def part_rows(part: str, rows) -> list[dict]:
    """`rows` (a list of objects, or one object) tagged `{"part": part, ...}`: the
    rows of a script that measures several kinds of case."""
    rows = [rows] if isinstance(rows, dict) else rows
    return [{"part": part, **row} for row in rows]


def rows_of(record: dict, part: str) -> list[dict]:
    """The rows of `record` tagged `part` (`part_rows`), without the tag."""
    return [{k: v for k, v in row.items() if k != "part"}
            for row in record.get("rows", []) if row.get("part") == part]


def load_results(path) -> dict:
    """A results file, checked against `results/SCHEMA.md`."""
    record = json.loads(Path(path).read_text())
    problems = schema_problems(record)
    if problems:
        raise ValueError(f"{path}: " + "; ".join(problems))
    return record


# ---- Timing -----------------------------------------------------------------------


def time_loop(step, x0, repeats: int, target_s: float = 0.1) -> float:
    """Seconds per iteration of `x <- step(x)` run inside a jitted `fori_loop`."""
    import jax

    @jax.jit
    def loop(x, count):
        return jax.lax.fori_loop(0, count, lambda i, y: step(y), x)

    def timed(fn):
        t = time.perf_counter()
        fn()
        return time.perf_counter() - t

    loop(x0, 1).block_until_ready()  # compile
    t = timed(lambda: loop(x0, 4).block_until_ready())
    count = int(min(2000, max(3, math.ceil(target_s / max(t / 4, 1e-7)))))
    times = [timed(lambda: loop(x0, count).block_until_ready()) / count
             for _ in range(repeats)]
    return statistics.median(times)


def fft_floor(n: int, dtype, repeats: int) -> float:
    """Seconds of ONE padded convolution irfft2(rfft2(p, 2n x 2n) * k)[:n, :n] in a
    jitted loop (`time_loop`): the floor of one CG iteration per coupled block."""
    import jax.numpy as jnp

    k = jnp.full(
        (2 * n, n + 1),
        0.5,
        dtype=jnp.complex128 if dtype == jnp.float64 else jnp.complex64,
    )
    x0 = jnp.linspace(0.0, 1.0, n * n, dtype=dtype).reshape(n, n)

    def naive(p):
        q = jnp.fft.irfft2(jnp.fft.rfft2(p, s=(2 * n, 2 * n)) * k, s=(2 * n, 2 * n))
        return q[:n, :n] + x0

    return time_loop(naive, x0, repeats)


def convolution_times(op, spectrum, n: int, dtype, repeats: int) -> dict:
    """Time of one padded FFT convolution: naive rfft2/irfft2 and the library's own
    (`op.inverse(op.forward(p) * spectrum)`), each per iteration of `time_loop`."""
    import jax.numpy as jnp
    import numpy as np

    # Scale the kernel so that max|k| = 1/2: x <- conv(x) + x0 stays bounded (no
    # overflow or denormals however many iterations run). The extra add is O(n^2).
    k = (0.5 / jnp.max(jnp.abs(spectrum))) * spectrum
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n), indexing="ij")
    x0 = jnp.asarray(np.sqrt(np.maximum(1 - 4 * (x * x + y * y), 0)), dtype=dtype)

    def naive(p):
        q = jnp.fft.irfft2(jnp.fft.rfft2(p, s=(2 * n, 2 * n)) * k, s=(2 * n, 2 * n))
        return q[:n, :n] + x0

    def pruned(p):
        return op.inverse(op.forward(p) * k) + x0

    return {
        "naive": time_loop(naive, x0, repeats),
        "pruned": time_loop(pruned, x0, repeats),
    }
