"""The scale benchmark (pipeline/tools/scale.py): its input checks, the packing measurement, and
one tiny sweep through every stage (slow: five commands)."""
import json

import pytest

from pipeline.tools import scale


@pytest.mark.parametrize("args", [["--sizes", "15"], ["--sizes", "x"], ["--epochs", "0"],
                                  ["--packing", "0"], ["--baseline", "/nonexistent"],
                                  ["--sampled", "100", "--sample", "200"],
                                  ["--sampled", "105"], ["--sampled", "100", "--sample", "5"],
                                  ["--sweeps", "0"]])
def test_bad_input_is_exit_2(args, tmp_path, capsys):
    assert scale.main([*args, "--out", str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")
    assert not (tmp_path / "s.json").exists()


def test_packing_counts_files_and_reads_back_what_it_wrote():
    out = scale.packing(30)
    assert out["per_trial"]["files"] == 60 and out["packed"]["files"] == 2
    assert all(out[k]["write_ms"] > 0 and out[k]["read_ms"] > 0 for k in out)


@pytest.mark.slow
def test_a_tiny_sweep_records_every_stage(tmp_path):
    out = tmp_path / "scale.json"
    assert scale.main(["--sizes", "10", "--epochs", "2", "--workers", "1", "--out",
                       str(out)]) == 0
    (r,) = json.loads(out.read_text())["results"]
    assert r["size"] == 10 and r["files"] == 20
    for stage in scale.STAGES:
        assert r[stage]["wall_s"] > 0 and r[stage]["cpu_s"] > 0 and r[stage]["peak_mb"] > 0


def test_planning_plans_every_trial_then_takes_the_saved_plan():
    out = scale.planning(scale.REPO, 40, 2, 1)
    assert out["plan"]["trials"] == out["plan_saved"]["trials"] == 40
    assert out["plan"]["cpu_s"] > 0 and out["peak_mb"] > 0


@pytest.mark.slow
def test_a_sampled_sweep_plans_all_and_runs_the_sample(tmp_path):
    out = tmp_path / "scale.json"
    assert scale.main(["--sampled", "40", "--sample", "10", "--epochs", "2", "--workers", "1",
                       "--out", str(out)]) == 0
    (r,) = json.loads(out.read_text())["results"]
    assert r["size"] == 40 and r["sampled"] == 10 and r["files"] == 20
    assert r["plan"]["trials"] == 40
    for stage in scale.STAGES:
        assert r["estimated_cpu_s"][stage] == pytest.approx(
            r[stage]["cpu_ms_per_trial"] * 40 / 1000, abs=0.06)


def test_the_last_lines_give_the_start_up_numbers_against_their_targets():
    stage = lambda cpu: dict(wall_s=cpu, cpu_s=cpu, peak_mb=1.0)  # noqa: E731
    smoke = dict({s: stage(c) for s, c in zip(scale.SMOKE_STAGES, (2.0, 1.5, 3.25))},
                 code="/x/checkout", cpu_s=6.75)
    sweeps = [dict(code="/x/checkout", size=s, aggregate_one=stage(c))
              for s, c in ((1000, 1.1), (10_000, 1.75))]
    assert scale.headline(sweeps, [smoke]) == [
        "cached make smoke (/x/checkout): 6.75 s CPU (simulate 2.00, aggregate 1.50, report "
        "3.25); target at most 8 s",
        "aggregate after one changed trial of 10,000 (/x/checkout): 1.75 s CPU; target at most 2 s"]
    assert scale.headline(sweeps[:1], []) == []


def test_the_start_up_numbers_are_medians_of_alternating_runs(monkeypatch, tmp_path):
    """aggregate_one: `repeat` runs per checkout, the checkouts alternating (a shared machine's
    load falls on both alike), recorded as the median with every run's CPU; the headline says
    so."""
    calls, cpu = [], iter([3.0, 1.0, 1.0, 2.0, 2.0, 9.0])
    stage = lambda c: dict(wall_s=c, cpu_s=c, peak_mb=1.0)  # noqa: E731

    def prepare(code, size, epochs, workers):
        return {"code": str(code), "size": size,
                **{s: stage(1.0) for s in scale.STAGES[:-1]}}, tmp_path / str(code)[-1]

    def changed_once(code, root, size, epochs):
        calls.append(str(code))
        return stage(next(cpu))

    monkeypatch.setattr(scale, "prepare", prepare)
    monkeypatch.setattr(scale, "changed_once", changed_once)
    a, b = scale.paired([scale.Path("/x/a"), scale.Path("/x/b")], 10_000, 10, 1, True, 3)
    assert calls == ["/x/a", "/x/b"] * 3
    assert a["aggregate_one"]["cpu_s"] == 2.0 and a["aggregate_one"]["runs_cpu_s"] == [3, 1, 2]
    assert b["aggregate_one"]["cpu_s"] == 2.0 and b["aggregate_one"]["runs_cpu_s"] == [1, 2, 9]
    assert scale.headline([a], []) == [
        f"10,000 trials, {s} (/x/a): CPU 1.000x the baseline's (the median of the paired "
        "sweeps')" for s in scale.STAGES[:-1]] + [
        "aggregate after one changed trial of 10,000 (/x/a): 2.00 s CPU (median of 3: 3.00, "
        "1.00, 2.00); target at most 2 s"]


def test_sweeps_alternate_with_the_baselines_and_give_medians_and_paired_ratios(
        tmp_path, monkeypatch):
    """--sweeps 3 with a baseline: this checkout's and the baseline's sweeps alternate (reversed
    every other round); each stage is the median of its sweeps and carries the median of the
    sweep-by-sweep CPU ratios; only the latest sweep's root is kept for aggregate_one."""
    calls, cpu = [], {"a": iter([4.0, 6.0, 5.0]), "b": iter([5.0, 5.0, 10.0])}

    def prepare(code, size, epochs, workers):
        calls.append(code)
        c = next(cpu[code])
        root = tmp_path / f"{code}{len(calls)}"
        root.mkdir()
        return dict(code=code, size=size, files=2 * size, **{
            s: dict(wall_s=c, cpu_s=c, peak_mb=1.0) for s in scale.STAGES[:-1]}), root

    monkeypatch.setattr(scale, "prepare", prepare)
    monkeypatch.setattr(scale, "changed_once", lambda code, root, size, epochs: dict(
        wall_s=1.0, cpu_s=1.0 if root.exists() else 99.0, peak_mb=1.0))
    a, b = scale.paired(["a", "b"], 10, 2, 1, False, 1, sweeps=3)
    assert calls == ["a", "b", "b", "a", "a", "b"]
    assert a["simulate"]["cpu_s"] == 5.0 and b["simulate"]["cpu_s"] == 5.0
    assert a["simulate"]["cpu_ratio"] == 0.8  # median of 4/5, 6/5, 5/10
    assert "cpu_ratio" not in b["simulate"] and a["aggregate_one"]["cpu_s"] == 1.0
    assert not any(tmp_path.iterdir())  # every root removed at the end
