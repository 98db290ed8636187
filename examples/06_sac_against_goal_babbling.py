# %% [markdown]
# # Goal Babbling against SAC with hindsight relabelling, on the same growing arm
#
# The 5-DOF arm grows from half to full size while it learns to reach. A reinforcement-learning
# agent, stable-baselines3's SAC with hindsight experience replay, learns on the Gymnasium
# environment gbgrowth/GrowingReach-v0 (one posture per episode, dense reward, growth counted in
# episodes); Goal Babbling learns by gbmodel's trial loop on the same body, growth schedule and
# kinematics (the environment's hand is gbmodel's: tests/pipeline/test_gym_env.py). Both are
# scored on the pipeline's held-out targets at the body's current size, in mm and in % of the
# full body's reach, against the number of forward evaluations (postures tried) each used, and
# the body finishes growing after the same number of them. Growth ends at GROWTH_EVALS; the
# comparison is read at SAC's budget.
#
# Run: `make gym-figure` (installs the extra [rl]: torch's CPU build, stable-baselines3), or
# `.venv/bin/python examples/06_sac_against_goal_babbling.py [--steps N --seeds K --out DIR]`.
# The committed figure docs/img/sac_vs_goal_babbling.png was made by `make gym-figure` (its
# numbers: docs/gym.md).

# %%
import argparse
import json
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gbmodel  # noqa: E402
import pipeline.envs  # noqa: E402,F401  (registers gbgrowth/GrowingReach-v0)

REPO = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd()
LEARNERS = {"goal_babbling": "Goal Babbling (batch, the paper's)",
            "online_goal_babbling": "online Goal Babbling"}


# %% [markdown]
# The two learners, each returning its held-out error against forward evaluations.

# %%
def sac_curve(steps: int, growth_evals: int, seed: int, every: int) -> tuple:
    """SAC + HER on the growing arm: the held-out error [m] after every `every` steps (one
    step: one posture, one forward evaluation), and the reach [m] of the full-size body."""
    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC, HerReplayBuffer

    torch.set_num_threads(1)
    env = gym.make("gbgrowth/GrowingReach-v0", body="arm5", growth="proportional",
                   period=growth_evals, mode="posture", reward="dense")
    model = SAC("MultiInputPolicy", env, seed=seed, learning_starts=min(500, steps // 4),
                batch_size=128,
                replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"),
                policy_kwargs=dict(net_arch=[128, 128]), verbose=0)
    reach = model.get_env().envs[0].unwrapped.reach
    x, err = [], []
    for _ in range(every, steps + 1, every):
        model.learn(every, reset_num_timesteps=False)
        arm = model.get_env().envs[0].unwrapped
        goals = arm.heldout_goals()
        actions, _ = model.predict(arm.observe(goals), deterministic=True)
        x.append(arm.evaluations)
        err.append(float(np.linalg.norm(arm.hand(actions) - goals, axis=1).mean()))
    return np.array(x), np.array(err), reach


def goal_babbling_curve(learner: str, evals: int, growth_evals: int, seed: int) -> tuple:
    """Goal Babbling's held-out error [m] against its forward evaluations, with the growth
    ending after growth_evals of them (T_G in epochs of its own samples)."""
    module, params = gbmodel.TrialSpec(learner={"name": learner}).make_learner()
    spe = module.samples_per_epoch(params, gbmodel.make_body("arm5"))
    period = max(1, round(growth_evals / spe))
    spec = gbmodel.TrialSpec(body={"name": "arm5"}, learner={"name": learner},
                             growth=dict(pattern="proportional", period=period, start_size=0.5,
                                         end_size=1.0), epochs=max(2, -(-evals // spe)))
    r = gbmodel.run_trial(spec, np.random.default_rng(seed))
    return r.epoch * spe, r.heldout_abs_error


# %% [markdown]
# Both learners on the same seeds, one figure and its numbers.

# %%
def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int, default=10_000, help="SAC's budget of forward evaluations")
    ap.add_argument("--seeds", type=int, default=2, help="trials per learner")
    ap.add_argument("--every", type=int, default=1000, help="SAC's evaluation interval [steps]")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "img")
    a = ap.parse_args(argv)
    growth_evals = a.steps // 2  # the body is full-grown half way through SAC's budget
    gb_evals = 100 * a.steps  # Goal Babbling's curves run on, beyond SAC's budget
    curves, t0 = {}, time.process_time()
    for learner in LEARNERS:
        runs = [goal_babbling_curve(learner, gb_evals, growth_evals, s) for s in range(a.seeds)]
        curves[learner] = (runs[0][0], np.stack([r[1] for r in runs]))
    t_gb = time.process_time() - t0
    runs = [sac_curve(a.steps, growth_evals, s, a.every) for s in range(a.seeds)]
    reach = runs[0][2]
    curves["sac_her"] = (runs[0][0], np.stack([r[1] for r in runs]))
    t_sac = time.process_time() - t_gb - t0
    numbers = {"budget_evaluations": a.steps, "growth_ends_after_evaluations": growth_evals,
               "seeds": a.seeds, "reach_m": round(reach, 4),
               "cpu_s": {"goal_babbling_both": round(t_gb, 1), "sac_her": round(t_sac, 1)}}
    for name, (x, err) in curves.items():
        k = int(np.searchsorted(x, a.steps, side="right")) - 1  # the last point within budget
        mean = err.mean(axis=0)
        numbers[name] = {"final_evaluations": int(x[-1]), "final_mm": round(1000 * mean[-1], 1)}
        if k >= 0:  # (none: its first evaluation comes after the budget)
            numbers[name].update(at_evaluations=int(x[k]), heldout_mm=round(1000 * mean[k], 1),
                                 heldout_pct_reach=round(100 * mean[k] / reach, 2))
    fig, ax = plt.subplots(figsize=(6, 3.8))
    for (name, (x, err)), style in zip(curves.items(), ("-", "--", "-")):
        label = LEARNERS.get(name, "SAC + HER (stable-baselines3)")
        ax.plot(x, 1000 * err.mean(axis=0), ls=style, lw=1.5,
                color="tab:red" if name == "sac_her" else "black", label=label)
    ax.axvline(growth_evals, color="0.6", lw=0.8, ls=":")
    ax.axvline(a.steps, color="tab:red", lw=0.8, ls=":")
    ax.text(growth_evals, ax.get_ylim()[0], " growth ends", color="0.4", fontsize=8,
            rotation=90, va="bottom")
    ax.set(xscale="log", yscale="log", xlabel="forward evaluations (postures tried)",
           ylabel="held-out error [mm]",
           title=f"arm5 growing 0.5 -> 1.0, mean of {a.seeds} trials each")
    sec = ax.secondary_yaxis("right", functions=(lambda mm: mm / (10 * reach),
                                                 lambda pct: pct * 10 * reach))
    sec.set_ylabel("% of reach")
    ax.legend(frameon=False, fontsize=8)
    fig.tight_layout()
    a.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out / "sac_vs_goal_babbling.png", dpi=110)
    (a.out / "sac_vs_goal_babbling.json").write_text(json.dumps(numbers, indent=1) + "\n")
    print(json.dumps(numbers, indent=1))
    return numbers


if __name__ == "__main__":
    main()
