"""Three robots from Gymnasium's MJCF files (conf/body/pusher.yaml, reacher.yaml,
humanoid_arm.yaml; the files ship in the `gymnasium` wheel, no `mujoco` needed) learned with the
new-robot recipe (their conf/body_learner/<body>_goal_babbling.yaml), the measurement in
docs/bodies.md ("Robots from MuJoCo models"):

    .venv/bin/python tests/gym_robots.py      # held-out errors and times, 3 seeds each

Used by tests/core/test_bodies_mjcf.py (the reach) and tests/e2e/test_gym_robots.py.
"""
from __future__ import annotations

NAMES = ("pusher", "reacher", "humanoid_arm")


def reach(body, samples: int = 20000) -> float:
    """The arm's reach: the largest distance of the hand from the shoulder over random postures
    within the limits [m], in the controlled coordinates. The shoulder is the origin of the
    body's frame: the Pusher's and the humanoid's `base` moves it there, the Reacher's first
    joint is there."""
    import numpy as np

    q = np.random.default_rng(0).uniform(-1.0, 1.0, size=(samples, body.m))
    return float(np.linalg.norm(body.forward(q), axis=-1).max())


def measure(name: str, growth: str, trials: int = 3, epochs: int = 1000, extra=()) -> dict:
    """Held-out errors [m], seconds per trial and the reach [m] of `trials` trials."""
    import time

    import numpy as np

    import gbmodel
    from pipeline.config import compose
    from pipeline.plan import plan

    cfg = compose([f"body={name}", f"growth={growth}", f"learner.epochs={epochs}",
                   f"trials.count={trials}", *extra])
    errors, seconds = [], []
    for t in plan(cfg):
        t0 = time.perf_counter()
        r = gbmodel.run_trial(gbmodel.TrialSpec.from_dict(t["spec"]),
                              np.random.default_rng(np.random.SeedSequence(**t["seed"])))
        seconds.append(time.perf_counter() - t0)
        errors.append(float(r.heldout_abs_error[-1]))
    return dict(errors=errors, seconds=seconds, reach=reach(gbmodel.make_body(t["spec"]["body"])))


if __name__ == "__main__":  # the measurement of docs/bodies.md
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    for name in [a for a in sys.argv[1:] if a in NAMES] or NAMES:
        for growth in ("none", "proportional"):
            r = measure(name, growth)
            err = r["errors"]
            print(f"{name} growth={growth}: reach {r['reach']:.3f} m, held-out after 1000 epochs "
                  f"{', '.join(f'{1e3 * e:.1f}' for e in err)} mm "
                  f"(max {100 * max(err) / r['reach']:.2f} % of the reach), "
                  f"{', '.join(f'{s:.1f}' for s in r['seconds'])} s per trial", flush=True)
