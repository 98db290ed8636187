"""A run's measured CPU times are written while it runs, not only when it ends: a run killed
without a chance to clean up (SIGKILL) keeps the times of what it finished (the report's
provenance sums them)."""
from pipeline import cache, simulate


A, B, C = ("a" * 20, "b" * 20, "c" * 20)  # trial keys (20 hexadecimal digits)


def _finished(monkeypatch, summary, key, cpu):
    monkeypatch.setattr(cache, "write_trial", lambda *a: None)  # the trial's files: not tested here
    summary.labels[key] = key
    simulate.record("unused", dict(key=key, labels={}), dict(status="ok", cpu=cpu), summary)


def test_times_are_written_as_trials_finish_every_so_often(tmp_path, monkeypatch):
    summary = simulate.Summary(figure="f", total=3, cached=0, times_dir=tmp_path)
    monkeypatch.setattr(simulate, "TIMES_EVERY_S", 3600.0)
    _finished(monkeypatch, summary, A, 1.5)
    assert cache.read_times(tmp_path) == {}  # not yet: within the interval
    monkeypatch.setattr(simulate, "TIMES_EVERY_S", 0.0)
    _finished(monkeypatch, summary, B, 2.0)
    assert cache.read_times(tmp_path) == {A: 1.5, B: 2.0}  # the run may die here
    monkeypatch.setattr(simulate, "TIMES_EVERY_S", 3600.0)
    _finished(monkeypatch, summary, C, 4.0)
    summary.keep_times(now=True)  # the run's end
    assert cache.read_times(tmp_path) == {A: 1.5, B: 2.0, C: 4.0}
    files = list((tmp_path / "logs" / "times").glob("*.json"))
    assert len(files) == 2 and summary.cpu == {A: 1.5, B: 2.0, C: 4.0}
    summary.keep_times(now=True)  # nothing new: no empty file
    assert len(list((tmp_path / "logs" / "times").glob("*.json"))) == 2


def test_a_summary_without_a_folder_writes_nothing(tmp_path, monkeypatch):
    summary = simulate.Summary(figure="f", total=1, cached=0)
    monkeypatch.setattr(simulate, "TIMES_EVERY_S", 0.0)
    _finished(monkeypatch, summary, A, 1.0)
    summary.keep_times(now=True)
    assert summary.cpu == {A: 1.0} and not (tmp_path / "logs").exists()
