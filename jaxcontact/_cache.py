"""`jc.enable_compilation_cache`: JAX's persistent compilation cache in a per-user
folder.

A coupled scene's program takes seconds to compile and a fraction of that to run; with
the cache a second process that solves a scene of the same shapes, dtypes and options
loads the compiled program from disk instead. The command line turns it on by default
(`jaxcontact run/fit --no-cache` or `JAXCONTACT_NO_CACHE=1` turn it off); notebooks and
scripts call `jc.enable_compilation_cache()` once, before their first solve.

A program that calls back into Python (`jc.solve(..., progress=...)`, or run-time
checks of traced inputs under `jit`) is never written to the cache (a JAX rule). A
fit traces its model without those checks (its material is positive by construction),
so `jaxcontact fit` keeps its programs.
"""

import os
from pathlib import Path


def default_cache_dir() -> Path:
    """`$JAXCONTACT_CACHE_DIR`, else `$XDG_CACHE_HOME/jaxcontact/xla`, else
    `~/.cache/jaxcontact/xla`."""
    if os.environ.get("JAXCONTACT_CACHE_DIR"):
        return Path(os.environ["JAXCONTACT_CACHE_DIR"]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "jaxcontact" / "xla"


def cache_disabled_by_environment() -> bool:
    """`JAXCONTACT_NO_CACHE` set to anything but "", "0" or "false"."""
    return os.environ.get("JAXCONTACT_NO_CACHE", "").strip().lower() not in ("", "0",
                                                                               "false")


def enable_compilation_cache(directory=None, *, min_compile_seconds: float = 1.0,
                             max_bytes: int = 2 * 1024**3) -> Path:
    """Turn on JAX's persistent compilation cache for this process.

    **Arguments:**

    - `directory`: where compiled programs are kept (created if missing); `None`:
      `default_cache_dir()`.
    - `min_compile_seconds`: only programs that took at least this long to compile
      are written [s] (the small helper programs are not worth a file).
    - `max_bytes`: the folder's size bound [bytes]; the least recently used entries
      are evicted beyond it. A bound also makes JAX lock the folder (with `filelock`)
      around every read and write: without the lock, a process reading an entry
      another one is still writing crashed (seen in two test processes sharing
      `~/.cache/jaxcontact/xla`).

    **Returns:** the cache folder. Entries are keyed by the program, the jax/jaxlib
    versions and the machine; stale ones are never read, and the folder may be deleted
    at any time.
    """
    import jax

    if min_compile_seconds < 0:
        raise ValueError("min_compile_seconds must be >= 0, got "
                         f"{min_compile_seconds!r}")
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, int) or max_bytes <= 0:
        raise ValueError(f"max_bytes must be a positive integer, got {max_bytes!r}")
    path = (Path(directory).expanduser() if directory is not None
            else default_cache_dir())
    path.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs",
                      float(min_compile_seconds))
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    jax.config.update("jax_compilation_cache_max_size", int(max_bytes))
    return path


def add_cache_argument(parser) -> None:
    """`--no-cache` on a command-line subcommand that solves (an argparse parser)."""
    parser.add_argument(
        "--no-cache", action="store_true",
        help="do not use the persistent compilation cache (default: on, in "
             "$JAXCONTACT_CACHE_DIR or ~/.cache/jaxcontact/xla; JAXCONTACT_NO_CACHE=1 "
             "also turns it off)")
