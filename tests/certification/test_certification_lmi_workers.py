"""LMI solves on the local cores: same answers in task order, and safe from unguarded scripts."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap

import pytest

from teleopkit.certification.lmi.workers import Background, map_solves, using_workers, workers

SCRIPT = """
import ast
import os
from teleopkit.certification.lmi.workers import map_solves
print("ran", os.getpid(), flush=True)
{guard}print(map_solves(pow, [(2, 3), (3, 2), (5, 1)]))
"""


def _run_script(tmp_path, source: str, workers: str = "2",
                *flags: str) -> subprocess.CompletedProcess:
    """Run ``source`` as a script file, with ``TELEOPKIT_WORKERS=workers``."""
    path = tmp_path / "script.py"
    path.write_text(textwrap.dedent(source))
    return subprocess.run([sys.executable, *flags, str(path)], capture_output=True, text=True,
                          timeout=120, env={**os.environ, "TELEOPKIT_WORKERS": workers},
                          check=False)


def _run(tmp_path, guard: str) -> subprocess.CompletedProcess:
    return _run_script(tmp_path, SCRIPT.format(guard=guard), "2", "-W", "always")


def test_results_come_back_in_task_order():
    assert map_solves(pow, [(2, k) for k in range(7)]) == [2**k for k in range(7)]


def test_an_unguarded_script_solves_in_its_own_process_and_runs_once(tmp_path):
    done = _run(tmp_path, "")
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("ran") == 1 and "[8, 9, 5]" in done.stdout
    assert "no 'if __name__" in done.stderr


def test_a_guarded_script_uses_the_workers(tmp_path):
    done = _run(tmp_path, 'if __name__ == "__main__":\n    ')
    assert done.returncode == 0, done.stderr
    assert "[8, 9, 5]" in done.stdout and "RuntimeWarning" not in done.stderr
    # each worker imports the guarded main module once, as __mp_main__, without its work
    assert done.stdout.count("ran") == 3


THREADS_SCRIPT = """
from threadpoolctl import threadpool_info

def blas_threads(_, threads=0):
    return max(pool["num_threads"] for pool in threadpool_info()), threads

if __name__ == "__main__":
    from teleopkit.certification.lmi.workers import map_solves
    print(map_solves(blas_threads, [(k,) for k in range(4)], share_cores=True))
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: no workers to share it")
def test_each_worker_gets_its_share_of_the_cores_for_blas(tmp_path):
    # two workers each running BLAS and Clarabel on every core solved a level of cells no
    # faster than one process
    done = _run_script(tmp_path, THREADS_SCRIPT, "2")
    assert done.returncode == 0, done.stderr
    share = (os.cpu_count() or 1) // 2
    for blas, solver in ast.literal_eval(done.stdout):
        assert 1 <= blas <= share and solver == share


def test_the_worker_count_is_read_from_the_environment(monkeypatch):
    monkeypatch.setenv("TELEOPKIT_WORKERS", "3")
    assert workers() == 3
    monkeypatch.setenv("TELEOPKIT_WORKERS", "many")
    with pytest.raises(ValueError, match="TELEOPKIT_WORKERS"):
        workers()


STARTER = """
from teleopkit.certification.lmi import workers as parallel
if __name__ == "__main__":
    parallel.start_workers()
    print("started", [len(parallel._Pool.executor._processes)] if parallel._Pool.executor
          else [])
    print(parallel.map_solves(pow, [(2, 3), (3, 2)]))
"""


@pytest.mark.parametrize(("count", "started"), [("2", "[2]"), ("1", "[]")])
def test_workers_start_before_the_first_solves(tmp_path, count, started):
    done = _run_script(tmp_path, STARTER, count)
    assert done.returncode == 0, done.stderr
    assert f"started {started}" in done.stdout and "[8, 9]" in done.stdout


def test_an_explicit_count_overrides_the_environment(monkeypatch):
    monkeypatch.setenv("TELEOPKIT_WORKERS", "3")
    with using_workers(1):
        assert workers() == 1
        with using_workers(None):
            assert workers() == 3
    assert workers() == 3
    with pytest.raises(ValueError, match="workers must be at least 1"), using_workers(0):
        pass


ONE_POOL = """
from teleopkit.certification.lmi import workers as parallel
if __name__ == "__main__":
    print(parallel.map_solves(pow, [(2, 3), (3, 2)]))
    first = parallel._Pool.executor
    with parallel.using_workers(3):
        print(parallel.map_solves(pow, [(2, 1), (2, 2), (2, 3)]))
    print("replaced", first is not parallel._Pool.executor, first._shutdown_thread)
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: no workers")
def test_one_pool_is_kept_and_replaced_when_its_size_changes(tmp_path):
    done = _run_script(tmp_path, ONE_POOL, "2")
    assert done.returncode == 0, done.stderr
    assert "[8, 9]" in done.stdout and "[2, 4, 8]" in done.stdout
    assert "replaced True True" in done.stdout


SHARED_FORMS_SCRIPT = """
import os
from certify.form_store import shared_directory

def directory(_):
    return str(shared_directory()), os.getpid()

if __name__ == "__main__":
    from teleopkit.certification.lmi.workers import map_solves, shutdown_workers
    seen = map_solves(directory, [(k,) for k in range(4)])
    print([(d == str(shared_directory()), p != os.getpid()) for d, p in seen])
    shutdown_workers()
    print(os.path.exists(seen[0][0]), shared_directory())
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: no workers")
def test_the_pool_shares_compiled_problems_through_one_directory_it_removes(tmp_path):
    done = _run_script(tmp_path, SHARED_FORMS_SCRIPT, "2")
    assert done.returncode == 0, done.stderr
    during, after = done.stdout.splitlines()
    assert ast.literal_eval(during) == [(True, True)] * 4  # the workers' directory is the main's
    assert after == "False None"


def test_a_background_search_runs_when_asked_with_one_worker():
    calls = []

    def search(x):
        calls.append(x)
        return map_solves(pow, [(x, 2), (x, 3)])

    with using_workers(1):
        later = Background(search, 3)
        assert calls == []  # nothing runs beside the caller without workers
        assert later.result() == [9, 27] and later.result() == [9, 27] and calls == [3]


def test_a_background_search_raises_in_the_caller():
    def broken():
        raise ValueError("no vertex")

    with using_workers(1), pytest.raises(ValueError, match="no vertex"):
        Background(broken).result()


BESIDE = """
import threading
from teleopkit.certification.lmi import workers as parallel

def search():
    solved = parallel.map_solves(pow, [(2, 3), (3, 2)])
    return threading.current_thread().name, parallel.workers(), solved

if __name__ == "__main__":
    with parallel.using_workers(2):
        later = parallel.Background(search)
        print("caller", parallel.map_solves(pow, [(2, 1), (2, 2)]))
    print("beside", later.result())
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: no workers")
def test_a_background_search_runs_on_a_thread_in_the_callers_context(tmp_path):
    done = _run_script(tmp_path, BESIDE, "3")
    assert done.returncode == 0, done.stderr
    assert "caller [2, 4]" in done.stdout
    # its own thread, the caller's worker count (not the environment's), the shared pool
    assert "beside ('teleopkit-lmi-background', 2, [8, 9])" in done.stdout
