"""The aggregate's statistics: per condition and epoch the curves over trials (curve_stats), per
condition the summary (summarize), each condition's rows kept from the previous set where its
inputs did not change (statistics)."""
from __future__ import annotations

import json
from functools import lru_cache
from itertools import islice, takewhile
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from . import io
from .aggregate_set import Previous, _checksum, _compact
from .measures import finals, growth_peak

if TYPE_CHECKING:  # pandas is imported where a figure is rebuilt (summarize): not when cached
    import pandas as pd

GROUP = [c for c in io.LABEL_COLUMNS if c != "trial"]
ERRORS = ("abs_error", "rel_error", "heldout_abs_error", "uniform_abs_error", "path_abs_error")


def curve_stats(trials: pd.DataFrame) -> pd.DataFrame:
    """Mean, std and quartiles over trials per condition and epoch (condition order kept)."""
    g = trials.groupby(GROUP + ["epoch"], sort=False)
    out = g[["samples", "size"]].mean()
    out["samples"] = out["samples"].astype("int64")
    for col in (c for c in ERRORS if c in trials):
        out[f"{col}_mean"] = g[col].mean()
        out[f"{col}_std"] = g[col].std(ddof=1)
        out[f"{col}_q25"] = g[col].quantile(0.25)
        out[f"{col}_q75"] = g[col].quantile(0.75)
    out["n_trials"] = g["trial"].count().astype("int64")
    return out.reset_index()


def summarize(trials: pd.DataFrame, curves: pd.DataFrame, conds: dict, paper: dict,
              fail_factor: float) -> pd.DataFrame:
    """One row per condition: final errors, the peak during growth (epochs 1 ... T_G + 1), trials
    that diverged, are missing or failed to bootstrap, the body's reach, the paper's accuracy."""
    import pandas as pd

    paper_abs = paper.get("final_abs_error")
    rows, last = [], finals(trials)
    final_of, curve_of = (dict(iter(f.groupby("condition", sort=False, observed=True)))
                          for f in (last, curves))  # one pass, not one per condition
    for name, c in conds.items():
        final, v, spec = final_of.get(name, last.iloc[:0]), c["variant"] or {}, c["spec"]
        row = {k: c["labels"][k] for k in GROUP}
        row.update(variant=v.get("label", ""), choice=v.get("choice", ""),
                   chosen=bool(v.get("chosen", False)),
                   start_size=spec["growth"]["start_size"], end_size=spec["growth"]["end_size"],
                   epochs=spec["epochs"], n_trials=int(len(final)), n_diverged=len(c["diverged"]),
                   n_run_failures=len(c["missing"]),
                   diverged_epochs=",".join(str(e) for e in c["diverged"].values()))
        for col in (c for c in ERRORS if c in final):
            row[f"final_{col}_mean"] = float(final[col].mean()) if len(final) else np.nan
            row[f"final_{col}_std"] = float(final[col].std(ddof=1)) if len(final) > 1 else np.nan
        cu = curve_of.get(name, curves.iloc[:0])
        cu = cu[cu["epoch"] <= c["labels"]["growth_period"] + 1]
        peak = growth_peak(cu) if c["labels"]["growth"] != "none" and len(cu) else None
        row["peak_abs_error_growth"] = peak[1] if peak else np.nan
        row["rise_abs_error_growth"] = peak[2] if peak else np.nan
        row["peak_epoch_growth"] = peak[0] if peak else -1
        median = final["rel_error"].median() if len(final) else np.nan
        row["n_bootstrap_failures"] = int((final["rel_error"] > fail_factor * median).sum())
        jumps = [t["largest_jump"] for t in c["trials"].values()]
        row["largest_jump_mean"] = float(np.mean(jumps)) if jumps else np.nan
        row["final_samples"] = int(final["samples"].max()) if len(final) else 0
        row["paper_final_abs_error"] = np.nan if paper_abs is None else float(paper_abs)
        row["reach"] = reach_of(spec)  # the final body's; the held-out error in % of it:
        row["final_heldout_abs_error_pct_reach"] = (  # comparable across robots of any size
            100 * row["final_heldout_abs_error_mean"] / row["reach"] if row["reach"] > 0
            else np.nan)
        rows.append(row)
    return pd.DataFrame(rows)


def stats_digest(name: str, c: dict, paper, fail_factor: float) -> str:
    """What a condition's rows of curves and summary are made of (with the libraries' versions)."""
    import pandas as pd

    body = [name, c["labels"], c["id"], c["variant"], sorted(c["trials"]), c["seals"],
            c["diverged"], c["missing"], paper, fail_factor, pd.__version__, np.__version__,
            pa.__version__]
    return _checksum(_compact(body))


def statistics(table: pa.Table, conds: dict, paper: dict, fail_factor: float,
               previous: Previous) -> tuple[pa.Table, pa.Table, dict]:
    """(curves, summary, stats for the manifest) of the trial curves `table`: a condition whose
    stats_digest is the previous set's keeps its rows, unless that set is unreadable or of
    another schema (another pandas)."""
    digests = {k: stats_digest(k, c, paper, fail_factor) for k, c in conds.items()}
    kept = {k for k, d in digests.items() if previous.stats.get(k, (None,))[0] == d}
    if kept and len(kept) < len(conds):
        try:
            return _computed(table, conds, paper, fail_factor, digests, kept, previous)
        except (OSError, ValueError, KeyError, IndexError, TypeError, pa.ArrowException):
            pass
    return _computed(table, conds, paper, fail_factor, digests)


def _computed(table, conds, paper, fail_factor, digests, kept=(), previous=None):
    """statistics() with the conditions `kept` taken from `previous`."""
    computed = {k: c for k, c in conds.items() if k not in kept}
    if kept:
        parts = [table.slice(min(e["row"] for e in c["trials"].values()),
                             sum(e["rows"] for e in c["trials"].values()))
                 for c in computed.values() if c["trials"]]  # a condition's rows are consecutive
        rows = pa.concat_tables(parts or [table.slice(0, 0)]).to_pandas()
        if set(rows["condition"]) != {k for k, c in computed.items() if c["trials"]}:
            raise ValueError("the computed conditions' rows are not theirs")
    else:
        rows = table.to_pandas()
    curves = curve_stats(rows)
    new = (io.frame_to_table(curves),
           io.frame_to_table(summarize(rows, curves, computed, paper, fail_factor)))
    if not kept:
        return (*new, _stats_record(new[0], conds, digests))
    old = previous.checked_table("curves.parquet"), previous.checked_table("summary.parquet")
    if not all(n.schema.equals(o.schema, check_metadata=True) for n, o in zip(new, old)):
        raise ValueError("the computed rows' schema is not the previous files'")
    at, parts = _stats_record(new[0], computed, digests), ([], [])
    for k in conds:
        (_, first, n, i), (curves_t, summary_t) = ((previous.stats[k], old) if k in kept
                                                   else (at[k], new))
        parts[0].append(curves_t.slice(first, n))
        parts[1].append(summary_t.slice(i, 1))
    curves_t, summary_t = (pa.concat_tables(p).combine_chunks() for p in parts)
    if summary_t.column("condition").to_pylist() != list(conds):
        raise ValueError("summary.parquet: the conditions are not the figure's")
    return curves_t, summary_t, _stats_record(curves_t, conds, digests)


def trials_file_table(table: pa.Table) -> pa.Table:
    """pa.Table.from_pandas(table.to_pandas(), schema=io.CURVE, preserve_index=False) without the
    round trip where no value is null or NaN: one chunk, its first row's pandas metadata."""
    floats = [f.name for f in io.CURVE if pa.types.is_floating(f.type)]
    if table.num_rows and not any(table.column(n).null_count for n in table.column_names) and \
            not any(np.isnan(table.column(n).to_numpy()).any() for n in floats):
        meta = pa.Table.from_pandas(table.slice(0, 1).to_pandas(), schema=io.CURVE,
                                    preserve_index=False).schema.metadata
        return table.combine_chunks().replace_schema_metadata(meta)
    return pa.Table.from_pandas(table.to_pandas(), schema=io.CURVE, preserve_index=False)


def _stats_record(curves: pa.Table, conds: dict, digests: dict) -> dict:
    """condition -> [its stats digest, first row in `curves`, rows, row in the summary]."""
    names = curves.column("condition").to_pylist()
    first, out = 0, {}
    for i, k in enumerate(conds):
        n = sum(1 for _ in takewhile(k.__eq__, islice(names, first, None)))
        out[k], first = [digests[k], first, n, i], first + n
    if first != len(names):
        raise ValueError("curves: rows of no condition of the figure")
    return out


def reach_of(spec: dict) -> float:
    """The reach [m] of a condition's body at its final size (gbmodel.workspace.reach)."""
    return _reach(json.dumps(spec["body"], sort_keys=True),
                  json.dumps(spec["growth"], sort_keys=True))


@lru_cache(maxsize=256)
def _reach(body_json: str, growth_json: str) -> float:
    import gbmodel

    body, g = gbmodel.make_body(json.loads(body_json)), json.loads(growth_json)
    try:  # the end body of its growth pattern (non-proportional: its own segments' sizes)
        k = gbmodel.Growth(**g).scales(body, g["end_size"])
    except (TypeError, ValueError, KeyError):
        k = np.full(body.m, float(g.get("end_size", 1.0)))
    return _reach_at(body_json, tuple(np.asarray(k, dtype=np.float64).tolist()))


@lru_cache(maxsize=256)
def _reach_at(body_json: str, factors: tuple) -> float:
    """A body's reach at `factors`, sampled once for conditions that end at it (20 ms each)."""
    import gbmodel
    from gbmodel import workspace

    return workspace.reach(gbmodel.make_body(json.loads(body_json)), np.array(factors))
