"""The files a training run keeps across resumes, in process: progress.csv (appended across segments, cut back to
the checkpoint a resume starts from, a torn last row dropped, widened when a key appears) and score.json."""

from __future__ import annotations

import json
import math

import pandas as pd
import pytest

from searchrl.train.logs import AppendingCSV, ResumableTensorBoard
from searchrl.train.run_record import read_score, run_score, write_score

STEP = "time/total_timesteps"


def test_a_new_log_starts_with_its_keys_and_widens_when_a_key_appears(tmp_path):
    path = tmp_path / "progress.csv"
    log = AppendingCSV(path)
    assert path.read_text() == "\n"  # an empty header, so a reader finds the file from the start
    log.write({STEP: 256, "train/loss": 0.5, "skipped": {"a": 1}, "listed": [1]}, {})
    log.write({STEP: 512, "train/loss": None}, {})  # no new key: appended
    assert path.read_text() == f"{STEP},train/loss\n256,0.5\n512,\n"
    log.write({STEP: 768, "team/found": 0.25, "team/F": 3}, {})  # new keys, sorted, at the end
    assert path.read_text() == f"{STEP},train/loss,team/F,team/found\n256,0.5,,\n512,,,\n768,,3,0.25\n"
    log.write({STEP: 1024, "team/F": 4}, {})  # appended, the keys it lacks left empty
    assert path.read_text().endswith("\n768,,3,0.25\n1024,,4,\n")
    log.close()
    assert list(tmp_path.iterdir()) == [path]


def test_a_resumed_log_keeps_the_rows_up_to_its_checkpoint_and_drops_a_torn_row(tmp_path):
    path = tmp_path / "progress.csv"
    path.write_text(f"{STEP},val\n256,0.1\n512,0.2\n,0.3\nstep?,0.4\n768,0.5\n1024,0.6\n1280,0.7")  # torn last row
    log = AppendingCSV(path, resume_step=768)
    # rows past 768 go (logged again after the resume); rows without a readable step sort before every checkpoint
    assert path.read_text() == f"{STEP},val\n256,0.1\n512,0.2\n,0.3\nstep?,0.4\n768,0.5\n"
    log.write({STEP: 1024, "val": 0.9}, {})
    assert path.read_text().endswith("768,0.5\n1024,0.9\n")
    clone = tmp_path / "clone.csv"  # a resume from the clone's step-0 checkpoint keeps its step-0 and stepless rows
    clone.write_text(f"{STEP},val\n0,0.1\n,0.2\nstep?,0.25\n256,0.3\n")
    AppendingCSV(clone, resume_step=0)
    assert clone.read_text() == f"{STEP},val\n0,0.1\n,0.2\nstep?,0.25\n"
    torn = tmp_path / "torn.csv"  # killed while writing the row of step 512: "51" is not a step of this run
    torn.write_text(f"{STEP},val\n256,0.1\n51")
    AppendingCSV(torn, resume_step=768)
    assert torn.read_text() == f"{STEP},val\n256,0.1\n"
    whole = tmp_path / "whole.csv"
    whole.write_text(f"{STEP},val\n256,0.1\n512,0.2\n")
    AppendingCSV(whole)  # no resume step: every whole row stays
    assert whole.read_text() == f"{STEP},val\n256,0.1\n512,0.2\n"


def _session_starts(folder) -> list[int]:
    """The steps of the restart markers in a TensorBoard folder's event files (TensorBoard hides events logged
    before such a marker at or past its step)."""
    from tensorboard.backend.event_processing.event_file_loader import EventFileLoader

    events = [e for f in sorted(folder.glob("events.*")) for e in EventFileLoader(str(f)).Load()]
    return [e.step for e in events if e.HasField("session_log")]


def test_tensorboard_purges_past_the_resume_step_only_on_resume(tmp_path):
    for folder, purge_step in (("fresh", None), ("resumed", 1025)):
        board = ResumableTensorBoard(str(tmp_path / folder), purge_step=purge_step)
        board.write({"val": 0.5}, {"val": None}, step=1280)
        board.close()
    assert len(list((tmp_path / "fresh").glob("events.*"))) == 1  # written where it was asked to write
    assert _session_starts(tmp_path / "fresh") == []
    assert _session_starts(tmp_path / "resumed") == [1025]


def _progress(tmp_path, rows: list[tuple[int, float | None]]) -> None:
    frame = pd.DataFrame({STEP: [s for s, _ in rows], "val/found_fraction": [v for _, v in rows], "x": 1.0})
    frame.to_csv(tmp_path / "progress.csv", index=False)


def test_the_score_averages_the_last_validations_and_says_which(tmp_path):
    _progress(tmp_path, [(0, 0.1), (256, None), (512, 0.2), (768, None), (1024, 0.5), (1024, 0.75)])
    record = run_score(tmp_path, last=3)
    assert record == {"score": pytest.approx(1.45 / 3), "metric": "val/found_fraction", "last": 3, "validations": 3,
                      "steps": [512, 1024, 1024]}  # fmt: skip
    assert run_score(tmp_path, last=10)["validations"] == 4 and run_score(tmp_path, last=1)["score"] == 0.75
    written = write_score(tmp_path, last=2)
    assert written["score"] == 0.625
    text = (tmp_path / "score.json").read_text()
    assert text == json.dumps(written, indent=1) + "\n" and read_score(tmp_path) == 0.625


@pytest.mark.parametrize("content", [None, "", f"{STEP},x\n256,1\n"])
def test_a_run_without_validations_scores_nan(tmp_path, content):
    if content is not None:
        (tmp_path / "progress.csv").write_text(content)
    record = run_score(tmp_path, last=3)
    assert math.isnan(record["score"]) and record["validations"] == 0 and record["steps"] == []
    assert math.isnan(read_score(tmp_path))  # no score.json: the run did not finish
