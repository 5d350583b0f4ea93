"""Refusals, stops and failed multirun jobs, in process: what searchrl/multirun.py makes of each (the sweeps in
tests/test_sweep.py and tests/test_faults.py run the same code in Hydra's own processes)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest
from hydra.core.utils import JobReturn, JobStatus
from hydra.types import RunMode
from omegaconf import OmegaConf

import searchrl.multirun as multirun
from searchrl.multirun import FAILED, FailedJobs, JobFailed, Stopped, in_sweep, summarize
from searchrl.world.config import ConfigError


def _hydra(mode: RunMode, sweep_dir: Path, num: int = 0):
    return OmegaConf.create({"hydra": {"mode": mode, "sweep": {"dir": str(sweep_dir)}, "job": {"num": num}}})


def _failed(error: BaseException, overrides: list[str] | None) -> JobReturn:
    job = JobReturn(overrides=overrides, status=JobStatus.FAILED)
    job._return_value = error
    return job


def test_a_failed_job_files_its_overrides_and_its_errors_first_line(tmp_path):
    callback = FailedJobs()
    sweep = tmp_path / "multirun" / "2026-11-29"  # not made yet: the first failure makes it
    config = _hydra(RunMode.MULTIRUN, sweep, num=7)
    callback.on_job_end(config, _failed(RuntimeError("first line\nsecond line"), ["a=1", "b=x"]))
    callback.on_job_end(_hydra(RunMode.MULTIRUN, sweep, num=12), _failed(KeyboardInterrupt(), None))
    assert (sweep / FAILED / "7.txt").read_text() == "a=1 b=x\tfirst line\n"
    assert (sweep / FAILED / "12.txt").read_text() == "\tKeyboardInterrupt\n"  # no message: its type


def test_jobs_that_ran_and_single_runs_file_nothing(tmp_path):
    callback = FailedJobs()
    callback.on_job_end(_hydra(RunMode.MULTIRUN, tmp_path), JobReturn(overrides=["a=1"], status=JobStatus.COMPLETED))
    callback.on_job_end(_hydra(RunMode.RUN, tmp_path), _failed(RuntimeError("no"), ["a=1"]))
    assert not (tmp_path / FAILED).exists()


def test_a_continued_sweep_forgets_the_last_ones_failures_and_names_its_own_at_exit(tmp_path, monkeypatch):
    folder = tmp_path / FAILED
    folder.mkdir()
    (folder / "3.txt").write_text("a=1\told\n")
    (folder / "keep.log").write_text("not a job's file")
    registered = []
    monkeypatch.setattr(multirun.atexit, "register", lambda *call: registered.append(call))
    FailedJobs().on_multirun_start(_hydra(RunMode.MULTIRUN, tmp_path))
    assert sorted(p.name for p in folder.iterdir()) == ["keep.log"]
    assert registered == [(summarize, folder)]


def test_the_summary_names_each_failed_job_in_job_order(tmp_path, capsys):
    summarize(tmp_path)  # none failed: nothing
    assert capsys.readouterr().err == ""
    (tmp_path / "10.txt").write_text("seed=10\trefused:\tX \n")  # the line as filed, tabs and all
    (tmp_path / "2.txt").write_text("seed=2 algo.n_epochs=0\tnot allowed: X\n")  # only the newline goes
    summarize(tmp_path)
    assert capsys.readouterr().err == (
        "error: 2 job(s) of the multirun failed; the others ran:\n"
        "  #2 [seed=2 algo.n_epochs=0]: not allowed: X\n"
        "  #10 [seed=10]: refused:\tX \n"
    )


@pytest.fixture
def hydra_mode(monkeypatch):
    """Make Hydra's running config say the mode asked for (what a task function reads inside Hydra)."""

    def set_mode(mode: RunMode) -> None:
        monkeypatch.setattr(multirun.HydraConfig, "get", staticmethod(lambda: SimpleNamespace(mode=mode)))

    return set_mode


def _refuse() -> None:
    raise ConfigError("x=3 is not allowed: 1 or 2")


def _stop() -> None:
    raise Stopped(143)


def test_in_sweep_returns_what_the_task_returns(hydra_mode):
    hydra_mode(RunMode.RUN)
    assert in_sweep(lambda a, b: a + b, 2, 3) == 5


def test_a_single_run_refused_or_stopped_ends_with_its_line_and_status(hydra_mode, capsys):
    hydra_mode(RunMode.RUN)
    with pytest.raises(SystemExit) as refused:
        in_sweep(_refuse)
    assert refused.value.code == 2 and capsys.readouterr().err == "error: x=3 is not allowed: 1 or 2\n"
    with pytest.raises(SystemExit) as stopped:
        in_sweep(_stop)
    assert stopped.value.code == 143 and capsys.readouterr().err == ""


def test_a_multirun_job_refused_or_stopped_fails_alone(hydra_mode, capsys):
    hydra_mode(RunMode.MULTIRUN)
    with pytest.raises(JobFailed, match=r"^x=3 is not allowed: 1 or 2$"):
        in_sweep(_refuse)
    assert capsys.readouterr().err == "error: x=3 is not allowed: 1 or 2\n"
    with pytest.raises(JobFailed, match=r"^stopped with exit status 143$"):
        in_sweep(_stop)
    assert capsys.readouterr().err == ""


def test_hydra_reports_a_failed_job_in_its_line_not_a_traceback(capsys):
    """At a multirun's end Hydra raises the first failed job's exception and prints it: a refused job's is its line."""
    from hydra._internal.utils import run_and_report

    def sweep() -> None:
        raise JobFailed("x=3 is not allowed: 1 or 2")

    with pytest.raises(SystemExit):
        run_and_report(sweep)
    err = capsys.readouterr().err
    assert "x=3 is not allowed: 1 or 2" in err and "Traceback" not in err
