"""aggregate reads only what changed: each trial file once, nothing when nothing changed, one
trial when one changed; and the files it writes are those of a build from nothing."""
import os
from pathlib import Path

import pytest

from pipeline import aggregate, aggregate_set, aggregate_stats, cache, io, simulate
from conftest import files_of


@pytest.fixture
def sweep(tmp_path, compose_tiny):
    """A figure of two conditions (a growth period and a reference) x 3 trials, simulated."""
    cfg = compose_tiny(tmp_path, "trials.count=3", "conditions.references=[0.5]")
    assert simulate.simulate(cfg).failed == {}
    return cfg


@pytest.fixture
def reads(monkeypatch):
    """The trials whose files aggregate reads (pipeline.cache.read_trial), in order."""
    seen, real = [], cache.read_trial

    def counting(cache_dir, trial, curve=True):
        seen.append(trial["key"])
        return real(cache_dir, trial, curve)

    monkeypatch.setattr(cache, "read_trial", counting)
    return seen


def built_from_nothing(cfg, tmp_path) -> dict:
    fresh = cfg.copy()
    fresh.paths.aggregate = str(tmp_path / "fresh")
    assert aggregate.aggregate(fresh) == []
    return files_of(Path(fresh.paths.aggregate) / "custom")


def trial_files(cfg) -> list[Path]:
    return sorted((Path(cfg.paths.cache) / cache.TRIALS).rglob("*.json"))


def test_each_trial_file_is_read_once_and_unchanged_inputs_read_none(sweep, reads):
    assert aggregate.aggregate(sweep) == []
    assert len(reads) == 6 and len(set(reads)) == 6  # one read per trial, not a check and a read
    reads.clear()
    assert aggregate.aggregate(sweep) == []
    assert reads == []


def test_a_rewritten_trial_is_read_once_and_the_files_match_a_fresh_build(
        sweep, reads, tmp_path):
    assert aggregate.aggregate(sweep) == []
    side = trial_files(sweep)[2]
    side.write_bytes(side.read_bytes())  # rewritten (the same content, a new write)
    os.utime(side, ns=(1, 1))
    reads.clear()
    assert aggregate.aggregate(sweep) == []
    assert reads == [side.stem]
    reads.clear()
    assert aggregate.aggregate(sweep) == []
    assert reads == []
    folder = Path(sweep.paths.aggregate) / "custom"
    assert files_of(folder) == built_from_nothing(sweep, tmp_path)


def test_a_recomputed_trial_changes_the_aggregate_like_a_fresh_build(sweep, reads, tmp_path):
    assert aggregate.aggregate(sweep) == []
    curve = trial_files(sweep)[0].with_suffix(".parquet")
    curve.unlink()  # lost, then computed again
    problems = aggregate.aggregate(sweep)
    assert len(problems) == 1 and curve.name in problems[0]
    assert simulate.simulate(sweep).ran == 1
    reads.clear()
    assert aggregate.aggregate(sweep) == []
    assert reads == [curve.stem]
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


def test_a_file_damaged_after_aggregating_is_named_not_reused(sweep):
    assert aggregate.aggregate(sweep) == []
    curve = trial_files(sweep)[1].with_suffix(".parquet")
    curve.write_bytes(curve.read_bytes()[:20])
    problems = aggregate.aggregate(sweep)
    assert len(problems) == 1 and curve.name in problems[0] and "checksum" in problems[0]


@pytest.mark.parametrize("name", ["trials.parquet", "models.json", aggregate.INDEX])
def test_a_damaged_previous_aggregate_is_rebuilt_from_the_cache(sweep, tmp_path, name):
    assert aggregate.aggregate(sweep) == []
    folder = Path(sweep.paths.aggregate) / "custom"
    (io.set_of(folder) / name).write_bytes(b"garbage")
    sweep.trials.count = 4  # two trials more to read, six to reuse from the damaged set
    assert simulate.simulate(sweep).ran == 2
    assert aggregate.aggregate(sweep) == []
    assert files_of(folder) == built_from_nothing(sweep, tmp_path)


def test_labels_follow_the_plan_when_reused_rows_change_condition(tmp_path, compose_tiny):
    """A reused trial's rows take the labels of the condition that uses it now."""
    one = compose_tiny(tmp_path, "trials.count=2")
    assert simulate.simulate(one).failed == {}
    assert aggregate.aggregate(one) == []
    two = compose_tiny(tmp_path, "trials.count=2", "conditions.references=[0.5]")
    assert simulate.simulate(two).failed == {}
    assert aggregate.aggregate(two) == []
    assert files_of(Path(two.paths.aggregate) / "custom") == built_from_nothing(two, tmp_path)


def test_added_trials_are_the_only_ones_read(sweep, reads, tmp_path):
    assert aggregate.aggregate(sweep) == []
    sweep.trials.count = 4
    assert simulate.simulate(sweep).ran == 2
    reads.clear()
    assert aggregate.aggregate(sweep) == []
    assert len(reads) == 2
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


def test_an_edited_paper_block_rebuilds_the_aggregate(tmp_path, compose_tiny):
    """The experiment's paper block (the paper's numbers, its study, the figures it is judged
    on) is in the summary and models.json: changing it rebuilds the figure."""
    import pandas as pd

    for value in (0.02, 0.05):
        cfg = compose_tiny(tmp_path, "experiment=fig4", f"paper.final_abs_error={value}")
        simulate.simulate(cfg)
        aggregate.aggregate(cfg)
        summary = pd.read_parquet(Path(cfg.paths.aggregate) / "fig4" / "summary.parquet")
        assert set(summary["paper_final_abs_error"]) == {value}


def model_lines(cfg) -> dict[str, str]:
    lines = (io.set_of(Path(cfg.paths.aggregate) / "custom") / "models.json").read_text()
    return {ln.split('":', 1)[0]: ln for ln in lines.splitlines()[1:-1]}


def test_one_changed_trial_rewrites_the_model_line_of_its_condition_only(
        sweep, tmp_path, monkeypatch):
    from pipeline.tools import scale

    assert aggregate.aggregate(sweep) == []
    before = model_lines(sweep)
    assert len(before) == 2
    encoded, real = [], aggregate_set._compact
    monkeypatch.setattr(aggregate_set, "_compact", lambda obj: encoded.append(obj) or real(obj))
    scale.change_one_trial(Path(sweep.paths.cache))
    assert aggregate.aggregate(sweep) == []
    after = model_lines(sweep)
    assert len([k for k in after if after[k] != before[k]]) == 1
    # the other condition's line copied, and in the changed one only the changed trial's model
    # encoded (its two other trials' texts kept from the previous line, not parsed and encoded)
    models = [o for o in encoded if isinstance(o, dict) and "M" in o]
    assert not [o for o in encoded if isinstance(o, dict) and "trials" in o]
    assert len(models) == 1 and models[0]["key"] in after[next(k for k in after
                                                                if after[k] != before[k])]
    monkeypatch.undo()
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


def test_a_model_line_edited_in_place_is_not_copied(sweep, tmp_path):
    from pipeline.tools import scale

    assert aggregate.aggregate(sweep) == []
    models = io.set_of(Path(sweep.paths.aggregate) / "custom") / "models.json"
    text = models.read_text()
    models.write_text(text.replace('"largest_jump":', '"largest_jump":1'))  # valid JSON
    scale.change_one_trial(Path(sweep.paths.cache))
    assert aggregate.aggregate(sweep) == []
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


def test_aggregate_and_report_select_figures_by_one_rule(tmp_path):
    """Both stages take the figures the command line names (experiments=, or figure= when
    explicit) by aggregate.named_figures; an unknown one is one line naming the folder."""
    from omegaconf import OmegaConf

    from pipeline import report

    cfg = OmegaConf.create(dict(figure="fig4", experiments=None,
                                paths=dict(aggregate=str(tmp_path / "agg"))))
    assert report.selected(cfg, explicit=False) is None  # every aggregated figure
    with pytest.raises(FileNotFoundError, match=r"^figure=fig4: not aggregated under .*agg "
                                                r"\(aggregated: none\)$"):
        report.selected(cfg, explicit=True)
    cfg.experiments = ["fig2", "fig5"]
    assert aggregate.named_figures(cfg, False, ["fig5", "fig2"], "x", "simulated") == ["fig2", "fig5"]
    with pytest.raises(FileNotFoundError, match=r"^figure=fig5: not simulated under x \(simulated: fig2\)$"):
        aggregate.named_figures(cfg, False, ["fig2"], "x", "simulated")


def test_each_model_line_is_checksummed_once(sweep, tmp_path, monkeypatch):
    """A line of models.json read from the previous set is checked against the checksum the
    manifest holds, which is then a copied line's checksum (its 1 MB per 1,000 trials not
    hashed a second time); the changed condition's new line is hashed once. Three lines, three
    hashes (before: five); the manifest is a fresh build's."""
    from pipeline.tools import scale

    assert aggregate.aggregate(sweep) == []
    hashed, real = [], aggregate_set._checksum
    monkeypatch.setattr(aggregate_set, "_checksum", lambda text: hashed.append(text) or real(text))
    scale.change_one_trial(Path(sweep.paths.cache))
    assert aggregate.aggregate(sweep) == []
    assert len(hashed) == 3 and len(set(hashed)) == 3  # two previous lines checked, one new
    monkeypatch.undo()
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


COMMAND_STATE = """
import atexit, gc, runpy, sys
import pyarrow as pa
def state():
    print("STATE", gc.isenabled(), pa.default_memory_pool().backend_name, gc.get_freeze_count() > 0,
          file=sys.stderr)
atexit.register(state)
sys.argv = ["pipeline.aggregate", *sys.argv[1:]]
runpy.run_module("pipeline.aggregate", run_name="__main__", alter_sys=True)
"""


def test_the_command_runs_without_cyclic_collection_on_the_system_allocator(sweep, tmp_path):
    """`python -m pipeline.aggregate` (one process, one run) turns Python's cyclic collector off
    before its imports (collected once per figure instead) and takes Arrow's buffers from the C
    library's allocator (mimalloc's cost 0.1 to 0.9 s of system time per 10,000-trial set);
    the API leaves the caller's process as it is. The files are a fresh build's."""
    import gc
    import subprocess
    import sys

    import pyarrow as pa

    from conftest import tiny_overrides
    from pipeline.config import REPO_ROOT

    pool, enabled = pa.default_memory_pool().backend_name, gc.isenabled()
    assert aggregate.aggregate(sweep) == []
    assert (pa.default_memory_pool().backend_name, gc.isenabled()) == (pool, enabled)
    env = {k: v for k, v in os.environ.items() if k != "ARROW_DEFAULT_MEMORY_POOL"}
    args = tiny_overrides(tmp_path, "trials.count=3", "conditions.references=[0.5]")
    scale_change = "from pipeline.tools import scale; import sys, pathlib; " \
                   "scale.change_one_trial(pathlib.Path(sys.argv[1]))"
    env["PYTHONPATH"] = str(REPO_ROOT)
    subprocess.run([sys.executable, "-c", scale_change, sweep.paths.cache], check=True, env=env)
    out = subprocess.run([sys.executable, "-c", COMMAND_STATE, *args], capture_output=True,
                         text=True, cwd="/", env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "STATE False system True" in out.stderr, out.stderr
    assert "1 of 1 figure(s) rebuilt" in out.stdout + out.stderr
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


def test_one_changed_trial_computes_the_statistics_of_its_condition_only(
        sweep, tmp_path, monkeypatch):
    """curves.parquet and summary.parquet: a condition none of whose inputs changed (its stats
    digest) keeps its rows from the previous set; the statistics are computed over the changed
    condition's rows only, and the files are those of computing every condition."""
    from pipeline.tools import scale

    assert aggregate.aggregate(sweep) == []
    seen, real = [], aggregate_stats.curve_stats
    monkeypatch.setattr(aggregate_stats, "curve_stats",
                        lambda t: seen.append(sorted(set(t["condition"]))) or real(t))
    scale.change_one_trial(Path(sweep.paths.cache))
    assert aggregate.aggregate(sweep) == []
    assert len(seen) == 1 and len(seen[0]) == 1  # one condition of two
    monkeypatch.undo()
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


@pytest.mark.parametrize("name", ["curves.parquet", "summary.parquet"])
def test_an_edited_statistics_file_is_not_copied_from(sweep, tmp_path, name):
    """A previous curves.parquet or summary.parquet that is a readable table but not the one
    written (a value edited) is not the source of any row: the statistics are computed."""
    import pyarrow as pa
    import pyarrow.compute as pc

    from pipeline.tools import scale

    assert aggregate.aggregate(sweep) == []
    path = io.set_of(Path(sweep.paths.aggregate) / "custom") / name
    table = io.read_table(path)
    column = table.schema.get_field_index("n_trials")
    table = table.set_column(column, table.field(column),
                             pc.add(table.column(column), pa.scalar(1, pa.int64())))
    io.write_table(path, table)  # a valid Parquet file, other numbers
    scale.change_one_trial(Path(sweep.paths.cache))
    assert aggregate.aggregate(sweep) == []
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


def test_an_edited_trials_file_is_not_copied_from(sweep, tmp_path):
    """A previous trials.parquet that is a readable table but not the one written (an error
    edited) is not the source of any trial's rows: every trial is read from the cache."""
    import pyarrow.compute as pc

    from pipeline.tools import scale

    assert aggregate.aggregate(sweep) == []
    path = io.set_of(Path(sweep.paths.aggregate) / "custom") / "trials.parquet"
    table = io.read_table(path)
    column = table.schema.get_field_index("abs_error")
    table = table.set_column(column, table.field(column),
                             pc.multiply(table.column(column), 2.0))
    io.write_table(path, table)  # a valid Parquet file, other numbers
    scale.change_one_trial(Path(sweep.paths.cache))
    assert aggregate.aggregate(sweep) == []
    assert files_of(Path(sweep.paths.aggregate) / "custom") == built_from_nothing(sweep, tmp_path)


@pytest.mark.parametrize("hole", [None, "nan", "null"])
def test_trials_file_is_the_tables_pandas_round_trip(tmp_path, hole):
    """trials.parquet, written without converting the whole table to pandas and back, has the
    bytes of that round trip (pandas' metadata; one chunk though the table has one per
    condition); a table with a NaN (which the round trip stores as null) or a null is
    converted."""
    import numpy as np
    import pyarrow as pa

    rng = np.random.default_rng(1)

    def part(condition, n):
        cols = {f.name: (pa.array(np.full(n, condition), f.type) if pa.types.is_string(f.type)
                         else pa.array(rng.integers(0, 9, n), f.type) if pa.types.is_integer(f.type)
                         else pa.array(rng.random(n), f.type)) for f in io.CURVE}
        return pa.Table.from_pydict(cols, schema=io.CURVE)

    table = pa.concat_tables([part("a", 5), part("b", 7)])
    if hole is not None:
        errors = table.column("heldout_abs_error").to_pylist()
        errors[3] = float("nan") if hole == "nan" else None
        table = table.set_column(table.schema.get_field_index("heldout_abs_error"),
                                 io.CURVE.field("heldout_abs_error"),
                                 pa.chunked_array([pa.array(errors, pa.float64())]))
    assert table.column("figure").num_chunks == 2
    fast, slow = tmp_path / "fast.parquet", tmp_path / "slow.parquet"
    io.write_table(fast, aggregate.trials_file_table(table))
    io.write_table(slow, pa.Table.from_pandas(table.to_pandas(), schema=io.CURVE,
                                              preserve_index=False))
    assert fast.read_bytes() == slow.read_bytes()
