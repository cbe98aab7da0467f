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
import shutil  # noqa: E402
import tempfile  # noqa: E402

import pytest  # noqa: E402

from jaxcontact import enable_compilation_cache  # noqa: E402


_SHARED_CACHE = "JAXCONTACT_TEST_CACHE_DIR"
_FULL_OPTIMIZATION = "JAXCONTACT_TEST_FULL_OPTIMIZATION"
_LEGACY_EMITTERS = "--xla_cpu_use_fusion_emitters=false"


def _quick_compile(config) -> bool:
    """Whether this run compiles with JAX's `jax_disable_most_optimizations` and XLA's
    legacy fusion emitters: the default selection (`-m 'not slow'`) unless
    `JAXCONTACT_TEST_FULL_OPTIMIZATION=1`. Its programs are small and their time is
    mostly compilation; the first flag lowers LLVM's optimisation level (measured:
    tests/test_gradients.py 129 -> 90 s), the emitters halve the code generation
    (200 -> 118 s on another machine). The slow suite, the benchmarks and users
    compile fully optimised."""
    return (os.environ.get(_FULL_OPTIMIZATION) != "1"
            and "not slow" in (config.option.markexpr or ""))


def pytest_configure(config):
    """Quick compilation for the default selection (`_quick_compile`), and one
    persistent compilation cache for the test processes of a run (a fresh folder,
    removed at the end): a program one process compiled, another loads instead of
    compiling it again. `JAXCONTACT_TEST_CACHE_DIR=off` leaves the cache out."""
    config.pluginmanager.register(_GroupInNodeId(), "jaxcontact-xdist-group-ids")
    if _quick_compile(config):
        os.environ["JAX_DISABLE_MOST_OPTIMIZATIONS"] = "1"  # subprocesses too
        jax.config.update("jax_disable_most_optimizations", True)
        # XLA's older (elemental) fusion emitters: half the compile time of a coupled
        # program, 20 % slower to run (benchmarks/notes/compile_cache.md). Read when
        # the CPU client starts, i.e. at the first computation, after this hook.
        flags = os.environ.get("XLA_FLAGS", "")
        if _LEGACY_EMITTERS not in flags:
            os.environ["XLA_FLAGS"] = f"{flags} {_LEGACY_EMITTERS}".strip()
    if os.environ.get(_SHARED_CACHE) == "off":
        return
    if not hasattr(config, "workerinput") and _SHARED_CACHE not in os.environ:
        # The controlling process (or a run without xdist): the workers it starts
        # inherit the folder through the environment.
        os.environ[_SHARED_CACHE] = tempfile.mkdtemp(prefix="jaxcontact-tests-xla-")
        config._jaxcontact_cache_owner = True
    enable_compilation_cache(os.environ[_SHARED_CACHE], min_compile_seconds=0.3)


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups
def pytest_collection_modifyitems(config, items):
    """Under `--dist loadgroup` (pyproject addopts) the tests of a file that use a
    module-scoped fixture of that file run in one test process: split over two, each
    process would build the fixture (a solve, a fit) again."""
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if info is None or item.get_closest_marker("xdist_group"):
            continue
        path = item.nodeid.split("::")[0]
        shared = any(d.scope == "module" and d.baseid == path
                     for name in info.names_closure
                     for d in info.name2fixturedefs.get(name, ()))
        if shared:  # the group: the file's name without ".py"
            item.add_marker(pytest.mark.xdist_group(path.rsplit("/", 1)[-1][:-3]))


class _GroupInNodeId:
    """`--dist loadgroup` on pytest 9: pytest-xdist (3.8) names an item's group by
    appending `@group` to `item._nodeid`, the scheduler's only clue, but pytest 9
    builds `nodeid` from `item._id`, so each group ran on both workers. The same
    suffix, set where pytest 9 reads it (only where xdist's did not take)."""

    @pytest.hookimpl(trylast=True)  # after xdist's own attempt
    def pytest_collection_modifyitems(self, config, items):
        if not getattr(config.option, "loadgroup", False):
            return
        for item in items:
            names = sorted({str(m.args[0] if m.args else m.kwargs.get("name",
                                                                      "default"))
                            for m in item.iter_markers("xdist_group")})
            suffix = "@" + "_".join(names)
            if names and not item.nodeid.endswith(suffix):
                from _pytest.nodeid import NodeId  # pytest 9

                item._id = NodeId.parse(item.nodeid + suffix)


def pytest_unconfigure(config):
    if getattr(config, "_jaxcontact_cache_owner", False):
        shutil.rmtree(os.environ.pop(_SHARED_CACHE), ignore_errors=True)


def _memory_maps() -> int:
    try:
        with open("/proc/self/maps") as maps:
            return maps.read().count("\n")
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
