"""Shared fixtures: paths to the project and ../shared, the numpy versions of the compiled loops, a clean py_trees
blackboard for every test, and
the agent's document and fake ports for the agent tests; a data directory of the suite's own; and how a parallel
run (pytest-xdist, as ./test runs the suite) hands the tests out to its workers."""

from __future__ import annotations

import gc
import importlib.util
import json
import logging
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from hypothesis import settings

from atemr.fsm.spec import AgentSpec, load_agent
from atemr.trees.context import clear_blackboard
from atemr.trees.fakes import RecordingLink, RecordingPort

# Property tests are deterministic like the rest of the suite: the same examples on every run (CI's and a
# newcomer's alike). ATEMR_TEST_HYPOTHESIS=explore draws fresh random examples to hunt for new counterexamples.
# No deadline: an example's duration is not what they test, and a loaded 2-core CI machine would fail them.
settings.register_profile("deterministic", derandomize=True, print_blob=True, deadline=None)
settings.register_profile("explore", derandomize=False, print_blob=True, deadline=None)
settings.load_profile("explore" if os.environ.get("ATEMR_TEST_HYPOTHESIS") == "explore" else "deterministic")

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
AGENT_YAML = ROOT / "trees" / "agent.yaml"


@pytest.fixture
def shared_dir() -> Path:
    """``../shared`` beside the checkout; tests that need it skip with a clear message when absent."""
    if not SHARED.is_dir():
        pytest.skip(f"../shared is not beside the checkout (looked for {SHARED})")
    return SHARED


@pytest.fixture(scope="session")
def numpy_baselines() -> ModuleType:
    """``benchmarks/numpy_baselines.py``: the numpy versions the compiled loops replaced, which they must answer as."""
    path = ROOT / "benchmarks" / "numpy_baselines.py"
    spec = importlib.util.spec_from_file_location("numpy_baselines_under_test", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(autouse=True)
def clean_blackboard() -> Iterator[None]:
    """py_trees keeps the blackboard at class level: every test (any that builds an agent or a robot)
    starts and ends with it empty."""
    clear_blackboard()
    yield
    clear_blackboard()


@pytest.fixture(autouse=True)
def root_logger_restored() -> Iterator[None]:
    """An in-process ``atemr`` ``main()`` configures logging as the command line does: a stderr handler on
    the root logger (this test's captured stream, closed afterwards) and the root level from ``--log-level``.
    Put both back, and the ``transitions`` logger's level, so no later test logs into a closed stream or
    loses its warnings to an ``ERROR`` level left behind (``caplog`` only sees records the level lets by)."""
    root = logging.getLogger()
    transitions = logging.getLogger("transitions")
    handlers, level, transitions_level = list(root.handlers), root.level, transitions.level
    yield
    for handler in list(root.handlers):
        if handler not in handlers and getattr(handler, "_atemr", False):
            root.removeHandler(handler)
    root.setLevel(level)
    transitions.setLevel(transitions_level)


@pytest.fixture(scope="session")
def agent_spec() -> AgentSpec:
    return load_agent(AGENT_YAML)


@pytest.fixture
def port() -> RecordingPort:
    return RecordingPort()


@pytest.fixture
def link() -> RecordingLink:
    return RecordingLink()


# -- running on several workers (pytest-xdist; ./test runs ``-n auto``) --------------------------------------------
#
# Three things keep a parallel run as sound as a serial one, and short:
#
# * one worker per module: the tests of a module are one unit of work, so its module-scoped fixtures (a recorded
#   patrol, a mapped flat) are built once, as in a serial run;
# * the longest first: modules holding a ``slow`` test are handed out before the rest, so no worker is left
#   alone with a long module at the end;
# * tests that judge wall-clock timing (a rate kept under load, an answer within a second, a real-time robot,
#   a browser: every ``e2e`` test) are marked ``exclusive``: they are one unit of their own, handed out last, and
#   run while no other test runs anywhere (a file lock shared by the workers, held shared by every other test).
#   Their turn waits for no more than the test the other worker is running then, a short one by that time.
#
# The workers decide the units (they see the marks), and write them to a file in a directory the controller
# made for the run; the controller's scheduler (`_UnitScheduling`) reads it. pytest-xdist's own ``loadgroup``
# would do this with ``xdist_group`` marks, but pytest 9.2 ignores the node ids it rewrites to carry them
# (pytest-dev/pytest-xdist#1386). Run serially (``./test -n 0``, or plain ``pytest``), none of this does anything
# but the frozen heap of exclusive tests (`pytest_runtest_protocol`); ``--dist loadfile``, ``loadscope`` or
# ``worksteal`` use xdist's own schedulers (the lock still holds).

#: Where the controller tells its workers the run's directory (inherited with its environment; not ATEMR_...,
#: which the configuration would take for one of its keys).
RUN_DIR_ENV = "PYTEST_ATEMR_RUN_DIR"
#: The unit of the exclusive tests: one, so they run back to back on one worker.
EXCLUSIVE_UNIT = "exclusive"


def _exclusive(item: pytest.Item) -> bool:
    """Marked ``exclusive``, or a browser test (``e2e``: chromium against a server, often with a real-time robot,
    its waits and rhythms on the wall clock)."""
    return item.get_closest_marker("exclusive") is not None or item.get_closest_marker("e2e") is not None


def _module(nodeid: str) -> str:
    return nodeid.split("::", 1)[0]


def _is_worker(config: pytest.Config) -> bool:
    return hasattr(config, "workerinput")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """On an xdist worker: order slow modules first and exclusive tests last, and write each test's unit for the
    controller. Every worker collects the same items and writes the same file."""
    if not _is_worker(config) or RUN_DIR_ENV not in os.environ:
        return
    slow = {_module(item.nodeid) for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: 2 if _exclusive(item) else 0 if _module(item.nodeid) in slow else 1)  # stable
    units = {item.nodeid: EXCLUSIVE_UNIT if _exclusive(item) else _module(item.nodeid) for item in items}
    run_dir = Path(os.environ[RUN_DIR_ENV])
    partial = run_dir / f"units-{config.workerinput['workerid']}.json"  # type: ignore[attr-defined]
    partial.write_text(json.dumps(units))
    partial.replace(run_dir / "units.json")  # atomic: the controller reads a whole file


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """The controller's scheduler for ``--dist load`` (what ``-n`` alone gives) and ``loadgroup``: xdist's
    ``loadscope`` with the workers' units and their order."""
    if config.getvalue("dist") not in ("load", "loadgroup") or RUN_DIR_ENV not in os.environ:
        return None
    from xdist.scheduler import LoadScopeScheduling

    class _UnitScheduling(LoadScopeScheduling):  # type: ignore[misc]
        """Units of work as the workers wrote them, handed out in the workers' order of collection."""

        def __init__(self, config: pytest.Config, log: Any) -> None:
            super().__init__(config, log)
            config.option.loadscopereorder = False  # the order is ours: slow first, exclusive last
            self._units: dict[str, str] | None = None

        def _split_scope(self, nodeid: str) -> str:
            if self._units is None:  # read once every worker has collected (and so written the file)
                self._units = json.loads((Path(os.environ[RUN_DIR_ENV]) / "units.json").read_text())
            return self._units.get(nodeid, _module(nodeid))

    return _UnitScheduling(config, log)


class _RunLock:
    """A readers-writer lock shared by the workers of one run, on two lock files: every test holds ``run``
    shared, an exclusive test holds it exclusively. ``gate`` is taken briefly before either, so a waiting
    exclusive test keeps new shared holders out and is not starved."""

    def __init__(self, directory: Path) -> None:
        self._gate = open(directory / "gate.lock", "a")  # noqa: SIM115 (held for the whole session)
        self._run = open(directory / "run.lock", "a")  # noqa: SIM115
        self.held: int | None = None  # fcntl.LOCK_SH or LOCK_EX while held

    def acquire(self, exclusive: bool) -> None:
        import fcntl

        mode = fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH
        if self.held == mode:
            return
        self.release()
        fcntl.flock(self._gate, fcntl.LOCK_EX)
        try:
            fcntl.flock(self._run, mode)
        finally:
            fcntl.flock(self._gate, fcntl.LOCK_UN)
        self.held = mode

    def release(self) -> None:
        import fcntl

        if self.held is not None:
            fcntl.flock(self._run, fcntl.LOCK_UN)
            self.held = None

    def close(self) -> None:
        self.release()
        self._gate.close()
        self._run.close()


_RUN_LOCK = pytest.StashKey[_RunLock]()


def pytest_configure(config: pytest.Config) -> None:
    """No test touches the data directory of the person running the suite (``~/.local/share/atemr``: their maps,
    users and recordings, and a running robot's control socket): each pytest process gets its own, removed at the
    end. The controller of a distributed run makes the run's directory (its workers inherit the variable naming
    it); a worker opens the run lock there."""
    data_home = tempfile.mkdtemp(prefix="atemr-test-data-")
    previous = os.environ.get("XDG_DATA_HOME")
    os.environ["XDG_DATA_HOME"] = data_home

    def restore() -> None:
        if previous is None:
            os.environ.pop("XDG_DATA_HOME", None)
        else:
            os.environ["XDG_DATA_HOME"] = previous
        shutil.rmtree(data_home, ignore_errors=True)

    config.add_cleanup(restore)
    if _is_worker(config):
        if RUN_DIR_ENV in os.environ:
            lock = config.stash[_RUN_LOCK] = _RunLock(Path(os.environ[RUN_DIR_ENV]))
            config.add_cleanup(lock.close)
    elif config.getoption("numprocesses", None) and config.getvalue("dist") != "no":
        run_dir = tempfile.mkdtemp(prefix="atemr-xdist-")
        os.environ[RUN_DIR_ENV] = run_dir

        def cleanup() -> None:
            os.environ.pop(RUN_DIR_ENV, None)
            shutil.rmtree(run_dir, ignore_errors=True)

        config.add_cleanup(cleanup)


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Hold the run lock around a test's setup, call and teardown: shared, or exclusive for an exclusive test. An
    exclusive test followed by another keeps it, so the exclusive tests run as one block. Outside pytest-timeout's
    own wrapper (``tryfirst``): waiting for the lock is not the test's time.

    An exclusive test also runs with the process's older objects frozen (`gc.freeze`): a worker that has run a
    thousand tests holds a large heap, and a full collection of it stalls the process for 0.4-1.1 s (measured),
    long enough for a real-time robot's in-process motor emulators to fall silent and its driver to report a
    fault. Collected once and frozen when an exclusive block begins, unfrozen when it ends."""
    lock = item.config.stash.get(_RUN_LOCK, None)
    exclusive = _exclusive(item)
    block_goes_on = exclusive and nextitem is not None and _exclusive(nextitem)
    if exclusive and not gc.get_freeze_count():
        gc.collect()
        gc.freeze()
    try:
        if lock is not None:
            lock.acquire(exclusive)
        yield
    finally:
        if lock is not None and not block_goes_on:
            lock.release()
        if exclusive and not block_goes_on:
            gc.unfreeze()
