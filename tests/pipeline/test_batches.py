"""Short trials travel to a worker in batches, long ones alone; the results are the same."""
from pipeline import execute
from pipeline.config import compose
from pipeline.plan import plan


def trials(tmp_path, *overrides):
    return plan(compose([f"paths.root={tmp_path}", "body=arm5", *overrides]))


def test_short_trials_are_batched_in_order_and_long_ones_alone(tmp_path):
    short = trials(tmp_path, "learner.epochs=10", "trials.count=500", "conditions.periods=[5]")
    long = trials(tmp_path, "learner.epochs=100000", "trials.count=2", "conditions.periods=[5]")
    todo = long + short
    cut = execute.batches(todo, 2)
    assert [t for b in cut for t in b] == todo  # every trial once, in order
    assert cut[0] == long[:1] and cut[1] == long[1:]  # each long trial alone
    assert all(1 <= len(b) <= execute.MAX_BATCH for b in cut)
    assert max(len(b) for b in cut) == execute.MAX_BATCH  # the short ones share tasks
    few = execute.batches(short[:32], 2)
    assert len(few) == execute.BATCH_SHARE * 2  # few trials: still spread over the workers


def test_batched_pool_gives_each_trial_its_own_result(tmp_path):
    todo = trials(tmp_path, "learner.epochs=3", "trials.count=12", "conditions.periods=[2]")
    got = list(execute.local(todo, 2))
    assert sorted(t["key"] for t, _ in got) == sorted(t["key"] for t in todo)
    assert all(r["key"] == t["key"] and r["status"] == "ok" for t, r in got)
