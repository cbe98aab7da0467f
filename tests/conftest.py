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
