"""Side by side in one run: the fast path's time per trial-epoch of arm5 and the iCub at the
paper's settings (pipeline.tools.bench's specs), a baseline checkout against this one, each in child
processes timed in CPU seconds (less sensitive to a shared machine than wall time), interleaved
A B B A ...; prints medians and the ratio this / baseline.

    python -m pipeline.tools.bench_compare BASELINE_DIR [ROUNDS] [REPEATS] [LEARNER]

BASELINE_DIR: another checkout, e.g. `git archive <commit> | tar -x -C /tmp/base`; LEARNER:
goal_babbling (the default: the batch fast path) or online_goal_babbling (pipeline.tools.bench's
online trials).
"""
from __future__ import annotations

import json
import statistics
import subprocess
import sys
from pathlib import Path

HERE = str(Path(__file__).resolve().parents[2])
CHILD = r'''
import json, sys, time
import numpy as np, gbmodel
from pipeline.tools.bench import EPOCHS, paper_spec


def time_trial(spec, seed=0):
    """CPU seconds per epoch of one trial (process time: less sensitive to a shared machine)."""
    t0 = time.process_time()
    gbmodel.run_trial(gbmodel.TrialSpec.from_dict(spec), np.random.default_rng(seed))
    return (time.process_time() - t0) / spec["epochs"]


out, learner = {}, sys.argv[2]
path = "online" if learner == "online_goal_babbling" else "fast"
for body in ("arm5", "icub"):
    spec = paper_spec(body, EPOCHS[path][body], True, learner)
    time_trial(paper_spec(body, 10, True, learner))
    out[body] = [time_trial(spec, s) * 1e6 for s in range(int(sys.argv[1]))]
print(json.dumps(out))
'''


def main(baseline: str, rounds: int = 4, reps: int = 3, learner: str = "goal_babbling") -> dict:
    """Medians [us per trial-epoch] per body and tree; prints them with the ratios."""
    TREES = {"baseline": str(Path(baseline).resolve()), "this": HERE}
    res = {t: {"arm5": [], "icub": []} for t in TREES}
    for r in range(rounds):
        for t, path in (TREES.items() if r % 2 == 0 else reversed(list(TREES.items()))):
            p = subprocess.run([sys.executable, "-c", CHILD, str(reps), learner], cwd=path, capture_output=True,
                               text=True, env={"PYTHONPATH": path, "PATH": "/usr/bin:/bin"})
            assert p.returncode == 0, p.stderr[-2000:]
            d = json.loads(p.stdout.strip().splitlines()[-1])
            for b in d:
                res[t][b] += d[b]
    for b in ("arm5", "icub"):
        m = {t: statistics.median(res[t][b]) for t in TREES}
        print(f"{b}: baseline {m['baseline']:.1f} us/trial-epoch, this {m['this']:.1f} "
              f"us/trial-epoch, ratio this/baseline {m['this'] / m['baseline']:.3f} "
              f"(medians of {len(res['baseline'][b])})")
    return res


if __name__ == "__main__":
    main(sys.argv[1], *(int(a) for a in sys.argv[2:4]), *sys.argv[4:5])
