import os

# Two test processes (pytest-xdist, pyproject addopts): on a GPU, neither may take
# most of its memory up front.
os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")
# The command-line tests run `main` in the test process: they must not turn on the
# user's persistent compilation cache for every later test (the cache test sets its
# own folder and clears this).
os.environ["JAXCONTACT_NO_CACHE"] = "1"

import jax  # noqa: E402


# Validation runs in float64 (float32 tests convert explicitly).
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")


import gc  # noqa: E402

import pytest  # noqa: E402


def _memory_maps() -> int:
    try:
        with open("/proc/self/maps") as maps:
            return sum(1 for _ in maps)
    except OSError:  # not Linux
        return 0


@pytest.fixture(autouse=True)
def _release_compiled_programs():
    """Free the compiled programs of a test process when its memory maps near the
    kernel's limit (`vm.max_map_count`, 65530 by default): each coupled program holds
    ~1500 maps (measured, 16^2-22^2 `lc` scenes), and a worker that compiled ~40 of them
    crashed inside XLA's compiler (segfault / abort in `backend_compile_and_load`)."""
    yield
    if _memory_maps() > 30000:
        jax.clear_caches()
        gc.collect()
