"""Stage 1, simulate: every trial of the config not cached yet, longest first on the engine,
each written to the cache as it finishes; a trial another run claimed is waited for; a failed or
diverged one is recorded and the others go on (exit 1 with a summary).

    python -m pipeline.simulate experiment=fig4     (-m growth.period=10,100; 'experiments=[a,b]')
"""
from __future__ import annotations

import json
import logging
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import gbmodel
import gbmodel.bodies
import gbmodel.trial
import hydra
from omegaconf import DictConfig, OmegaConf

from . import cache, checkpoint, cli, engines, execute, io
from .check import keeps_experiment
from .config import CONFIG_PATH, check_run
from .fingerprint import code_fingerprint
from .keys import canonical
from .plan import cost, cpu_seconds, plan, plan_conditions
from .planned import PLANNED, covers_code, misplanned, plan_digest
from .progress import Progress, estimate, fmt_duration

log = logging.getLogger("pipeline.simulate")
WAIT_POLL_S = 2.0
TIMES_EVERY_S = 60.0  # a long run writes its trials' measured CPU times this often


@dataclass
class Summary:
    figure: str
    total: int
    cached: int
    ran: int = 0
    failed: dict = field(default_factory=dict)  # key -> error (failed or diverged)
    labels: dict = field(default_factory=dict)  # key -> "condition trial i", for messages
    cpu: dict = field(default_factory=dict)  # key -> measured CPU seconds of the trials run
    times_dir: object = None  # paths.out: where keep_times writes them (None: nowhere)
    unkept: dict = field(default_factory=dict)  # cpu's entries not yet written
    kept_at: float = field(default_factory=time.monotonic)

    def keep_times(self, now: bool = False) -> None:
        """Write the times not yet written, at most every TIMES_EVERY_S unless now (a killed run
        loses at most that much of its provenance)."""
        if self.times_dir is None or not self.unkept:
            return
        if now or time.monotonic() - self.kept_at >= TIMES_EVERY_S:
            cache.write_times(self.times_dir, self.unkept)
            self.unkept, self.kept_at = {}, time.monotonic()

    def lines(self) -> list[str]:
        head = (f"[{self.figure}] {self.total} trials: {self.cached} cached, {self.ran} run, "
                f"{len(self.failed)} failed or diverged")
        return [head] + [f"  FAILED {self.labels[k]}: {e}" for k, e in self.failed.items()]


def record(cache_dir, trial: dict, result: dict, summary: Summary) -> None:
    """Write a finished trial (ok or diverged) to the cache, or its failure beside it."""
    key = trial["key"]
    if result["status"] in ("ok", "diverged"):
        if result.get("final") is not None:  # a continuation's base: its state, then the trial
            checkpoint.write(cache_dir, trial, result["final"])
        cache.write_trial(cache_dir, trial, result)
        cache.forget_failure(cache_dir, trial)
        if isinstance(result.get("cpu"), (int, float)):
            summary.cpu[key] = summary.unkept[key] = result["cpu"]
            summary.keep_times()
    if result["status"] != "ok":
        summary.failed[key] = result["error"]
        where = summary.labels[key]
        log.error("[%s] %s %s: %s", summary.figure, where, result["status"],
                  result.get("traceback", result["error"]))
    if result["status"] == "failed":
        io.write_json(cache.failure_path(cache_dir, trial),
                      dict(key=key, labels=trial["labels"], error=result["error"]))
    summary.ran += 1


@dataclass
class Job:
    figure: str
    paper: dict
    trials: list
    experiment: str | None = None


def jobs_of(cfg: DictConfig, overrides: list[str] = (), notes: list | None = None) -> list[Job]:
    """The figures this run plans (`experiments=[a, b]`: each composed with the other overrides),
    from paths.out/planned/ where the same plan_digest was planned before. notes: filled with
    the learner_notes, kept in the saved plan (a planned run imports no learner)."""
    engines.check(cfg.engine.name)  # this stage submits: the engine's package is needed
    experiment = None if cfg.get("experiments") else _experiment_of(cfg)
    saved = Path(cfg.paths.out) / PLANNED / f"{plan_digest(cfg, [overrides, experiment])}.json"
    jobs = None
    try:
        packed = io.read_json(saved, need=("jobs", "specs"))
        wrong = misplanned(packed["specs"], packed["jobs"])
        if wrong is not None:  # a cache whose content is not its keys': never run
            log.warning("warning: %s: %s (edited or damaged); planned again", saved, wrong)
        elif still_planned(packed):
            jobs = unpack_jobs(packed)
    except FileNotFoundError:
        pass
    except (OSError, ValueError, TypeError, KeyError, IndexError, AttributeError) as err:
        log.warning("warning: %s: damaged (%s); planned again", saved,
                    str(err).splitlines()[0] if str(err) else type(err).__name__)
    if jobs is None:
        jobs = plan_jobs(cfg, overrides, experiment)
        packed = {**pack_jobs(jobs), "notes": learner_notes(t for j in jobs for t in j.trials),
                  "covered": covers_code()}
        io.write_json(saved, packed, compact=True)
    else:
        check_run(cfg)
    kept = packed.get("notes")
    if notes is not None:
        notes[:] = (kept if isinstance(kept, list) and all(isinstance(n, str) for n in kept)
                    else learner_notes(t for j in jobs for t in j.trials))
    return jobs


def pack_jobs(jobs: list[Job]) -> dict:
    """Jobs as plain data, each distinct trial spec stored once."""
    specs, index, seen = [], {}, {}  # seen: by object (a plan shares a condition's spec)
    out = []
    for j in jobs:
        trials = []
        for t in j.trials:
            ix = seen.get(id(t["spec"]))
            if ix is None:
                ix = index.setdefault(io.dump_json(t["spec"]), len(specs))
                seen[id(t["spec"])] = ix
                if ix == len(specs):
                    specs.append(t["spec"])
            trials.append({**{k: v for k, v in t.items() if k != "spec"}, "spec": ix})
        out.append({**vars(j), "trials": trials})
    return dict(specs=specs, jobs=out)


def still_planned(saved: dict) -> bool:
    """Whether saved jobs hold beyond plan_digest: every file a body reads has its planned bytes,
    every trial's code fingerprint is this process's (not computed where the digest covered the
    learners' files when planned and covers them now: parsing them was a fifth of a cached
    stage's start)."""
    specs = saved["specs"]
    for spec in specs:
        for section in gbmodel.bodies.READS:
            value = spec["body"].get(section)
            try:
                sha = gbmodel.bodies.source_digest(section, value)
            except (OSError, ValueError):
                return False
            if sha is not None and sha != value.get("sha256"):
                return False
    codes = {(specs[t["spec"]]["learner"]["name"], t["code"]) for j in saved["jobs"]
             for t in j["trials"]}
    return (saved.get("covered") is True and covers_code()) or all(
        code_fingerprint(name) == code for name, code in codes)


def unpack_jobs(saved: dict) -> list[Job]:
    specs = saved["specs"]
    return [Job(**{**j, "trials": [{**t, "spec": specs[t["spec"]]} for t in j["trials"]]})
            for j in saved["jobs"]]


def plan_jobs(cfg: DictConfig, overrides, experiment: str | None) -> list[Job]:
    names = list(cfg.get("experiments") or [])
    if not names:
        return [Job(cfg.figure, OmegaConf.to_container(cfg.paper), plan(cfg), experiment)]
    from .config import compose

    rest = [o for o in overrides if not o.lstrip("+~").startswith(("experiments=", "experiment="))]
    jobs = []
    for name in names:
        ecfg = compose([f"experiment={name}", *rest])
        trials = plan(ecfg)
        keeps_experiment([f"experiment={name}", *rest], trials)
        jobs.append(Job(ecfg.figure, OmegaConf.to_container(ecfg.paper), trials, name))
    return jobs


def _experiment_of(cfg: DictConfig) -> str | None:
    try:
        from hydra.core.hydra_config import HydraConfig

        return HydraConfig.get().runtime.choices.get("experiment")
    except ValueError:  # not under @hydra.main (the API): the figure is its own experiment
        return None


def simulate(cfg: DictConfig, overrides: list[str] = (), group: str | None = None,
             job: int = 0) -> Summary:
    """Run the config's trials that are not cached. group: the Hydra multirun whose jobs' plan
    records make one figure together (job: this one's number)."""
    notes = []
    jobs = jobs_of(cfg, overrides, notes)  # raises ConfigError before anything is written
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    cache_dir = Path(cfg.paths.cache)
    names = list(dict.fromkeys(j.figure for j in jobs))
    figure = ", ".join(names) if len(names) <= 3 else f"{len(names)} figures"
    trials = unique_trials(jobs)
    (cache_dir / cache.TRIALS).mkdir(parents=True, exist_ok=True)
    for folder in (cache_dir / cache.TRIALS).glob("*"):
        io.remove_stale_tmp(folder)
    todo, diverged = to_run(cache_dir, trials)
    costs = execute.costs_of(todo)  # each condition's once (sorting, progress, batches)
    todo.sort(key=lambda t: costs[t["key"]], reverse=True)
    summary = Summary(figure=figure, total=len(trials), cached=len(trials) - len(todo),
                      failed=diverged, times_dir=cfg.paths.out)
    summary.labels = {t["key"]: _where(t) for t in trials}
    claims = {t["key"]: cache.Claim(cache_dir, t) for t in todo}
    mine = [t for t in todo if claims[t["key"]].acquire()]
    elsewhere = [t for t in todo if claims[t["key"]].fh is None]
    done_now = [t for t in mine if finished(cache_dir, t)[0] is not None]  # by another run
    for t in done_now:  # between our look at the cache and our claim
        claims[t["key"]].release()
        mine.remove(t)
        summary.cached += 1
    mine, views = with_views(mine)
    saved = cpu_seconds(sum(costs[k] for k in views), 0)  # the cost model's, not spent
    costs.update(dict.fromkeys(views, 0.0))
    mine.sort(key=lambda t: costs[t["key"]], reverse=True)
    workers = 1 if execute.in_launcher_worker() else min(cfg.workers, max(len(mine), 1))
    log.info("[%s] %d trials: %d cached, %d to run on %d worker(s)%s%s", figure, len(trials),
             summary.cached, len(mine) + len(views), workers,
             f" ({len(views)} scored on another's learning: about "
             f"{fmt_duration(saved) if saved >= 60 else f'{saved:.1f} s'} of CPU not spent)"
             if views else "",
             f", {len(elsewhere)} being computed by another run" if elsewhere else "")
    progress = Progress(summary, todo, cost=lambda t: costs[t["key"]])
    ahead = estimate(mine, workers, progress.costs)  # a long run says what it costs first
    if ahead:
        print(f"[{figure}] {ahead}", file=sys.stderr, flush=True)
    try:
        run_mine(cfg, mine, claims, summary, progress, views)
        wait_for(elsewhere, cache_dir, claims, summary, progress)
    finally:
        progress.close()
        for c in claims.values():
            c.release()
        summary.keep_times(now=True)  # the report's provenance sums them
    for j in jobs:
        write_figure(cache_dir, j, group, job)
    return summary


def unique_trials(jobs: list[Job]) -> list[dict]:
    """Every trial of the jobs once, with the bases of their continuations (keep_state)."""
    unique = {}
    for j in jobs:
        for t in j.trials:
            unique.setdefault(t["key"], t)
    for t in list(unique.values()):
        b = t.get("base")
        if b is not None:
            unique[b["key"]] = {**unique.get(b["key"], b), "keep_state": True}
    return list(unique.values())


def to_run(cache_dir, trials: list[dict]) -> tuple[list[dict], dict]:
    """(the trials not cached, key -> error of those cached as diverged); a damaged one reruns."""
    todo, diverged = [], {}
    for t in trials:
        done, damaged = finished(cache_dir, t)
        if damaged:
            print(f"[{t['figure']}] recomputing {t['growth_label']} trial "
                  f"{t['labels']['trial']}: {damaged}", file=sys.stderr)
        if done is None:
            todo.append(t)
        elif done["status"] == "diverged":
            diverged[t["key"]] = f"{done['error']} (cached)"
    return todo, diverged


def with_views(trials: list[dict]) -> tuple[list[dict], dict]:
    """(the trials to run, key -> trial of the views): a trial whose learning is the first
    epochs of another's (the same body, growth, learner and seed; another evaluation, fewer
    epochs: a multiple of the draw block) is scored by that run on the way (gbmodel.run_trial's
    views), cached under its own key with the bytes it has alone."""
    groups, views, out, specs = {}, {}, [], {}
    for t in trials:  # a continuation or its base runs on its own
        spec = t["spec"]  # a condition's trials share one: its learning made canonical once
        if id(spec) not in specs:
            specs[id(spec)] = (spec, canonical({k: spec[k] for k in gbmodel.trial.LEARNING}))
        learning = t["key"] if "base" in t or t.get("keep_state") else (
            specs[id(spec)][1], canonical(t["seed"]), t["code"])
        groups.setdefault(learning, []).append(t)
    for group in groups.values():
        while group:
            lead = max(group, key=lambda t: t["spec"]["epochs"])
            rest = [t for t in group if t is not lead and (
                t["spec"]["epochs"] == lead["spec"]["epochs"]
                or t["spec"]["epochs"] % gbmodel.trial.DRAW_BLOCK == 0)]
            taken = {id(lead), *map(id, rest)}
            group = [t for t in group if id(t) not in taken]
            views.update((t["key"], t) for t in rest)
            out.append({**lead, "views": [dict(key=t["key"], spec=t["spec"]) for t in rest]}
                       if rest else lead)
    return out, views


def run_mine(cfg: DictConfig, mine: list[dict], claims: dict, summary: Summary,
             progress: Progress, views: dict | None = None) -> None:
    """The claimed trials on the engine; continuations after the others (their bases first);
    views: key -> trial scored by a trial of `mine` (with_views)."""
    cache_dir = Path(cfg.paths.cache)
    for name in {t["spec"]["learner"]["name"] for t in mine}:  # (a saved plan's run: not yet)
        code_fingerprint(name)  # handed to the pool's workers, which then parse no file
    for wave in ([t for t in mine if "base" not in t], [t for t in mine if "base" in t]):
        ready = []
        for t in wave:
            trial, failed = resumed(cache_dir, t)
            if failed is None:
                ready.append(trial)
                continue
            record(cache_dir, t, failed, summary)
            claims[t["key"]].release()
            progress.update(t, failed)
        for trial, result in engines.run(
                OmegaConf.to_container(cfg.engine), ready, cfg.workers, execute.run_one,
                logs=Path(cfg.paths.out) / "logs" / "submitit", warm_up=execute.warm_up,
                pool=execute.local, cost=cost):
            for t, r in [(trial, result), *_viewed(trial, result, views)]:
                record(cache_dir, t, r, summary)
                claims[t["key"]].release()
                progress.update(t, r)


def _viewed(trial: dict, result: dict, views: dict | None) -> list[tuple[dict, dict]]:
    """(view trial, its result) of each view a finished trial scored; failed with it."""
    out = []
    for v in trial.get("views", ()):
        r = result.get("views", {}).get(v["key"]) or dict(
            status="failed", key=v["key"], seconds=0.0, error=f"not scored: the trial learning "
            f"for it {result['status']} ({result.get('error')})")
        out.append((views[v["key"]], r))
    return out


def wait_for(elsewhere: list[dict], cache_dir, claims: dict, summary: Summary,
             progress: Progress) -> None:
    """Trials another run claimed: wait for them, or take one over if that run died."""
    while elsewhere:
        trial = elsewhere.pop(0)
        claim = claims[trial["key"]]
        if finished(cache_dir, trial)[0] is not None:
            summary.cached += 1
        elif claim.acquire() and finished(cache_dir, trial)[0] is not None:
            claim.release()
            summary.cached += 1
        elif claim.fh is not None:
            ready, result = resumed(cache_dir, trial)
            result = result or execute.run_one(ready)
            record(cache_dir, trial, result, summary)
            claim.release()
            progress.update(trial, result)
        else:
            elsewhere.append(trial)
            time.sleep(WAIT_POLL_S)


def finished(cache_dir, trial: dict) -> tuple[dict | None, str | None]:
    """cache.check; a continuation's base is finished only with its saved state."""
    done, damaged = cache.check(cache_dir, trial)
    if done is not None and trial.get("keep_state") and done["status"] == "ok" \
            and not checkpoint.has(cache_dir, trial):
        return None, None
    return done, damaged


def resumed(cache_dir, trial: dict) -> tuple[dict, dict | None]:
    """(the trial as a worker runs it, a continuation with its base's checkpoint, None), or
    (trial, a failed result) where the base has none (tried again next time)."""
    if "base" not in trial:
        return trial, None
    data, why = checkpoint.load(cache_dir, trial["base"])
    if data is None:
        return trial, dict(status="failed", error=f"a continuation of epoch "
                           f"{trial['start']['epoch']}: {why}", key=trial["key"], seconds=0.0)
    return {**trial, "resume": data}, None


def learner_notes(trials) -> list[str]:
    """The learners' optional `notes` on their settings and bodies, each once, in order."""
    out, seen, specs = {}, set(), {}
    for t in trials:
        if id(t["spec"]) in specs:  # a condition's trials share their spec (plan, unpack_jobs)
            continue
        specs[id(t["spec"])] = t["spec"]  # held: its id is not reused
        key = json.dumps([t["spec"]["learner"], t["spec"]["body"]], sort_keys=True)
        if key in seen:
            continue
        seen.add(key)
        spec = gbmodel.TrialSpec.from_dict(t["spec"])
        learner, params = spec.make_learner()
        if hasattr(learner, "notes"):
            out.update(dict.fromkeys(learner.notes(params, spec.make_body())))
    return list(out)


def _where(t: dict) -> str:
    v = t.get("variant")
    name = f"{v['label']} | {t['growth_label']}" if v else t["growth_label"]
    return f"{t['figure']}: {name} trial {t['labels']['trial']}"


def write_figure(cache_dir, j: Job, group: str | None, job: int) -> None:
    """The plan record of one figure; says so when it replaces an earlier run's."""
    record = cache.plan_record(j.figure, plan_conditions(j.trials), j.paper, j.experiment)
    record["job"] = job
    _, replaced = cache.write_plan(cache_dir, record, group)
    if replaced and group is None:
        print(f"[{j.figure}] now the {len(record['conditions'])} condition(s) of this run; it "
              f"replaces an earlier run's {replaced['conditions']} (name a run figure=NAME to "
              "keep both)", file=sys.stderr)


def before_sweep(n_jobs: int, jobs: list[list[dict]], cache_dir, workers: int) -> None:
    """The estimate of a sweep of `n_jobs` (progress.estimate) before its first job: the
    uncached trials of the `jobs` the check planned, the others counted at their mean."""
    todo = [t for job in jobs for t in job if finished(Path(cache_dir), t)[0] is None]
    ahead = estimate(todo, workers, jobs=(len(jobs), n_jobs))
    if ahead:
        print(ahead, file=sys.stderr, flush=True)


def run(cfg: DictConfig) -> int:
    summary = simulate(cfg, *cli.hydra_run())
    print("\n".join(summary.lines()), file=sys.stderr)
    return 1 if summary.failed else 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
