"""Stage 2, aggregate: the cache into one tidy table per figure, its statistics and summary.

    python -m pipeline.aggregate              # every figure in the cache
    python -m pipeline.aggregate figure=fig4  # one figure (or experiment=fig4)

For every figure (the conditions of its current plan group, pipeline.cache.figure_conditions,
each labelled by what differs between them) whose inputs changed, it writes as one set, under
paths.aggregate/<figure>/:
    trials.parquet    every trial's learning curve (pipeline.io.CURVE, concatenated)
    curves.parquet    per condition and epoch: mean, std (over trials, ddof 1), 25 % and 75 %
                      quantiles of abs_error and rel_error, and n_trials
    summary.parquet   per condition: final errors (the held-out one also in % of the body's
                      reach, gbmodel.workspace), peak error during growth, failures, diverged
    models.json       per condition and trial: the final model M and its snapshots (compact
                      JSON, one line per condition: a rebuild copies the line of a condition
                      whose trials did not change; manifest.json holds each line's checksum)
    manifest.json     the digest of the inputs (conditions, trials' seals, code): unchanged
                      inputs leave the figure as it is; the SHA-256 of the Parquet files: a
                      file of the set that is not the one written is never copied from
    index.parquet     per trial: its files' signature (pipeline.cache.signature), seal, status
                      and rows in trials.parquet; the next run reads only the trials whose
                      files changed and takes the others from this set
Only the trials of the plan are read, so stale cache entries never mix in. A trial that diverged
or failed is counted as such and left out of every mean; a damaged or missing file is named.
"""
from __future__ import annotations

import gc
import hashlib
import json
import logging
import os
import sys
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

if __name__ == "__main__":  # the command: no cyclic collection from here on (one_shot)
    gc.disable()

import hydra
import numpy as np
import pyarrow as pa
from omegaconf import DictConfig

from . import cache, cli, io
from .config import CONFIG_PATH
from .measures import finals, growth_peak
from .fingerprint import source_fingerprint
from .labels import condition_labels

if TYPE_CHECKING:  # pandas is imported where a figure is rebuilt (summarize): not when cached
    import pandas as pd

log = logging.getLogger("pipeline.aggregate")

GROUP = [c for c in io.LABEL_COLUMNS if c != "trial"]
ERRORS = ("abs_error", "rel_error", "heldout_abs_error")


def condition_order(c: dict) -> tuple:
    """Variants in their order, then growing bodies by period, then references by size (a
    stable sort: conditions that tie keep the order they were planned in)."""
    return (c["_variant_index"], c["growth"] == "none", c["growth_period"],
            c["spec"]["growth"]["end_size"])


def figure_conditions(cache_dir, figure: str) -> tuple[list[dict], dict, list[str]]:
    """The figure's conditions in order, each labelled by what differs between them."""
    conds, paper, problems = cache.figure_conditions(cache_dir, figure)
    variant_order = {}
    for c in conds:
        label = (c.get("variant") or {}).get("label")
        c["_variant_index"] = variant_order.setdefault(label, len(variant_order))
    conds = sorted(conds, key=condition_order)
    for c, label in zip(conds, condition_labels(conds)):
        c["label"] = label
    return conds, paper, problems


INDEX = "index.parquet"  # per trial of the aggregate: what was read, to reuse it next time
INDEX_SCHEMA = pa.schema([("key", pa.string()), ("condition", pa.string()),
                          ("trial", pa.int64()), ("status", pa.string()),
                          ("epoch", pa.int64()), ("seal", pa.string()),
                          ("signature", pa.string()), ("largest_jump", pa.float64()),
                          ("row", pa.int64()), ("rows", pa.int64())])


class Previous:
    """The figure's current aggregate, made by this stage's code: for each trial it read, the
    signature of the trial's files (pipeline.cache.signature), its seal, its model and its rows.
    A trial whose files still have that signature is taken from here instead of being read and
    checked again, so a rebuild reads only what changed. Anything unreadable here: nothing is
    reused (every trial is read from the cache)."""

    def __init__(self, folder: Path | None = None):
        self.index, self.where, self._table, self._texts, self._pieces = {}, None, None, None, {}
        self._finished = None
        self.lines = {}  # condition -> (id, checksum of its models.json line)
        self.stats = {}  # condition -> (stats_digest, first row in curves.parquet, rows, row in
        self._sums = {}  # summary.parquet); file -> its SHA-256 (the manifest's)
        if folder is None or not folder.exists():
            return
        try:
            where = io.set_of(folder)
            manifest = io.read_json(where / "manifest.json")
            if manifest.get("code") != code_of_stage():
                return
            index = io.read_table(where / INDEX, schema=INDEX_SCHEMA)
            names = index.column_names  # table.to_pylist()'s rows, built column by column
            rows = [dict(zip(names, r)) for r in zip(*(index.column(n).to_pylist() for n in names))]
            self.lines = {k: tuple(v) for k, v in manifest.get("models", {}).items()}
            self.stats = {k: tuple(v) for k, v in manifest.get("stats", {}).items()}
            self._sums = dict(manifest.get("sha256", {}))
        except (OSError, ValueError, TypeError):
            return
        self.index, self.where = {r["key"]: r for r in rows}, where

    def trials_of(self, condition: str) -> list[str]:
        """The finished trials (their indices) the previous aggregate holds for `condition`."""
        if self._finished is None:  # every condition's in one pass over the index
            self._finished = {}
            for r in self.index.values():
                if r["status"] != "diverged":
                    self._finished.setdefault(r["condition"], []).append(str(r["trial"]))
        return self._finished.get(condition, [])

    def table(self) -> pa.Table:
        if self._table is None:
            # the curves' own columns only: the labels are set again per condition, and their
            # strings cost nine tenths of reading the file (0.08 of 0.09 s, 10,000 trials)
            self._table = self.checked_table("trials.parquet", io.TRIAL_CURVE)
        return self._table

    def checked_table(self, name: str, schema: pa.Schema | None = None) -> pa.Table:
        """A file of the set whose bytes are those the manifest recorded (ValueError if not: an
        edited file is never copied from); with `schema`, its columns only."""
        data = (self.where / name).read_bytes()
        if hashlib.sha256(data).hexdigest() != self._sums.get(name):
            raise ValueError(f"{name}: not the file the manifest recorded")
        return io.parse_table(data, self.where / name, schema,
                              None if schema is None else schema.names)

    def text(self, condition: str) -> str:
        """The condition's line of the previous models.json (models_text), checked against the
        checksum the manifest recorded for it (ValueError if it differs or is not there)."""
        if self._texts is None:
            self._texts = {}
            lines = (self.where / "models.json").read_text().split("\n")
            decoder = json.JSONDecoder()
            for line in lines[1:-2] if lines[0] == MODELS_HEAD else ():
                if line:
                    name, end = decoder.raw_decode(line)
                    self._texts[name] = line[end + 1:].rstrip(",")
        text = self._texts.get(condition)
        if text is None or _checksum(text) != self.lines.get(condition, (None, None))[1]:
            raise ValueError(f"models.json: the line of {condition!r} is damaged")
        return text

    def pieces(self, condition: str) -> dict[str, str]:
        """trial -> the JSON text of its model in the condition's previous line (text(), checked):
        the line parsed key by key by json's decoder, each model cut where its value ends (not
        encoded again; ValueError if the line is not what model_line writes)."""
        if condition not in self._pieces:
            text, out = self.text(condition), {}
            decode, scan = _DECODER.raw_decode, json.decoder.scanstring
            pos, key = 1, None
            while text[pos - 1] in "{," and key != "trials":
                key, pos = scan(text, pos + 1)  # past the opening quote
                if text[pos] != ":":
                    break
                if key == "trials":
                    pos += 2
                    while text[pos - 1] in "{," and text[pos] == '"':
                        trial, pos = scan(text, pos + 1)
                        end = decode(text, pos + 1)[1]
                        out[trial], pos = text[pos + 1:end], end + 1
                    pos += text[pos - 1] == "{"  # no trial: past the closing brace
                else:
                    pos = decode(text, pos + 1)[1] + 1
            if key != "trials" or text[pos - 1:] != "}}" or text[0] != "{":
                raise ValueError(f"models.json: the line of {condition!r} is not a condition's")
            self._pieces[condition] = out
        return self._pieces[condition]


_DECODER = json.JSONDecoder()


def load_trials(cache_dir, figure: str, previous: Previous | None = None):
    """(conditions by label, paper, problems found) of the figure's trials: each trial's files
    read and checked once, or, where they did not change since `previous`, taken from there.
    Each condition lists its trials' entries (seal, status, and the curve table or the rows of
    the previous aggregate); curves_table and models() turn them into the figure's files."""
    previous = previous or Previous()
    conditions, paper, problems = figure_conditions(cache_dir, figure)
    conds = {}
    for cond in conditions:
        name, spec = cond["label"], cond["spec"]
        labels = dict(figure=figure, body=spec["body"]["name"], learner=spec["learner"]["name"],
                      growth=cond["growth"], growth_period=cond["growth_period"], condition=name)
        c = conds[name] = dict(labels=labels, spec=spec, variant=cond.get("variant"), id=cond["id"],
                               trials={}, diverged={}, missing=[], seals=[], entries=[])
        for t in sorted(cond["trials"], key=lambda t: t["trial"]):
            i = str(t["trial"])
            signature = cache.signature(cache_dir, t)  # before reading: a later write shows
            entry = previous.index.get(t["key"])
            if signature is None or entry is None or entry["signature"] != signature:
                entry = _read(cache_dir, t, signature)
            if isinstance(entry, str) or entry is None:
                why = entry or "not computed (run pipeline.simulate)"
                c["missing"].append(i)
                problems.append(f"{name} trial {i}: {why}")
                continue
            entry = dict(entry, trial=t["trial"], key=t["key"])
            c["seals"].append(entry["seal"])
            c["entries"].append(entry)
            if entry["status"] == "diverged":
                c["diverged"][i] = entry["epoch"]
            else:
                c["trials"][i] = entry
    return conds, paper, problems


def _read(cache_dir, t: dict, signature: str | None):
    """A trial's entry read from the cache; the reason if it is damaged, None if not run."""
    side, table, damaged = cache.read_trial(cache_dir, t)
    if side is None:
        return damaged
    entry = dict(seal=side["seal"], status=side["status"], epoch=side.get("epoch"),
                 signature=signature, table=table)
    if side["status"] != "diverged":
        entry["largest_jump"] = side["largest_jump"]
        entry["model"] = {"key": t["key"], "M": side["M"], "snapshots": side["snapshots"],
                          "largest_jump": side["largest_jump"]}
    return entry


def _fill(cache_dir, entries: list[dict]) -> None:
    """Read from the cache the entries that were to come from a previous aggregate that turned
    out unreadable (their files are checked again)."""
    for e in entries:
        if "table" not in e:
            fresh = _read(cache_dir, e, e["signature"])
            if not isinstance(fresh, dict):
                raise io.DamagedFile(f"trial {e['key']}: {fresh or 'gone'} while aggregating; "
                                     "run the stage again")
            e.update(fresh)


def curves_table(conds: dict, previous: Previous) -> pa.Table:
    """Every finished trial's curve in io.CURVE, in condition and trial order, with the labels
    of its condition (set once per condition). Each entry's row range in it is recorded."""
    parts, row = [], 0
    for c in conds.values():
        pieces, counts, trials = [], [], []
        for e in c["trials"].values():
            if "table" in e:
                piece = e["table"].select(io.TRIAL_CURVE.names)
            else:  # consecutive rows of the previous aggregate are taken as one slice
                piece = ("slice", e["row"], e["rows"])
                if pieces and isinstance(pieces[-1], tuple) and sum(pieces[-1][1:]) == e["row"]:
                    piece = ("slice", pieces[-1][1], pieces[-1][2] + e["rows"])
                    pieces.pop()
            pieces.append(piece)
            e["row"], e["rows"] = row, len(e["table"]) if "table" in e else e["rows"]
            row += e["rows"]
            counts.append(e["rows"])
            trials.append(e["trial"])
        if not pieces:
            continue
        old = previous.table().select(io.TRIAL_CURVE.names) if any(
            isinstance(p, tuple) for p in pieces) else None
        body = pa.concat_tables([old.slice(p[1], p[2]) if isinstance(p, tuple) else p
                                 for p in pieces])
        n = len(body)
        same = pa.array(np.zeros(n, dtype=np.int64))  # each label's one value, n times: a take
        # (pa.repeat of a string scalar cost 19 ms per 11,000 rows: 1 s of a 10,000-trial figure)
        cols = {k: pa.array([v], io.CURVE.field(k).type).take(same)
                for k, v in c["labels"].items()}
        cols["trial"] = pa.array(np.repeat(np.asarray(trials, dtype=np.int64), counts))
        cols.update({k: body.column(k) for k in io.TRIAL_CURVE.names})
        parts.append(pa.Table.from_pydict({k: cols[k] for k in io.CURVE_COLUMNS},
                                          schema=io.CURVE))
    return pa.concat_tables(parts) if parts else io.CURVE.empty_table()


MODELS_HEAD = '{"conditions":{'


def _checksum(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _compact(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"))


def models(conds: dict, previous: Previous) -> tuple[dict[str, str], dict[str, str]]:
    """Per condition, the JSON text of its spec, id and each finished trial's model (key, M,
    snapshots, largest jump; model_line), from the trial's sidecar or the previous aggregate,
    and the text's checksum (the manifest's). A condition whose id and finished trials are
    those of the previous aggregate, none read again, keeps its text as it was, checked against
    its checksum, which is then its checksum (not taken again: 10 MB of a 10,000-trial figure).
    In a condition that changed, a trial not read again keeps its model's text (Previous.pieces):
    only the models read are encoded."""
    out, sums = {}, {}
    for k, c in conds.items():
        before = previous.lines.get(k)
        same = (before is not None and before[0] == c["id"]
                and all("model" not in e for e in c["trials"].values())
                and sorted(c["trials"]) == sorted(previous.trials_of(k)))
        if same:
            out[k], sums[k] = previous.text(k), before[1]
            continue
        kept = previous.pieces(k) if any("model" not in e for e in c["trials"].values()) else {}
        out[k] = model_line(c["spec"], c["id"], {
            i: _compact(e["model"]) if "model" in e else kept[i] for i, e in c["trials"].items()})
        sums[k] = _checksum(out[k])
    return out, sums


def model_line(spec: dict, cid: str, trials: dict[str, str]) -> str:
    """_compact({"spec": spec, "id": cid, "trials": {trial: model}}) from each trial's model
    already encoded (`trials`: trial -> its compact JSON): the same text, keys in the same
    (sorted) order."""
    models = ",".join(f"{json.dumps(i)}:{trials[i]}" for i in sorted(trials))
    return f'{{"id":{_compact(cid)},"spec":{_compact(spec)},"trials":{{{models}}}}}'


def models_text(fig: str, paper, texts: dict[str, str]) -> str:
    """models.json: {"conditions": ..., "figure": ..., "paper": ...} as compact JSON with sorted
    keys, each condition on a line of its own (whitespace JSON allows between values)."""
    body = ",\n".join(f"{json.dumps(k)}:{texts[k]}" for k in sorted(texts))
    return (f"{MODELS_HEAD}\n{body}\n}},\"figure\":{json.dumps(fig)},"
            f"\"paper\":{_compact(paper)}}}\n")


def refresh_index(conds: dict, previous: Previous) -> None:
    """Inputs unchanged, but some trials' files were rewritten with the same content (their
    seals match): record their new signatures, so that the next run does not read them again.
    The index is replaced alone, in place: no other file of the set depends on signatures."""
    fresh = [e for c in conds.values() for e in c["entries"] if "table" in e]
    for e in fresh:
        known = previous.index.get(e["key"])
        if known is None or known["seal"] != e["seal"]:
            return
        e["row"], e["rows"] = known["row"], known["rows"]
    if fresh:
        io.write_table(previous.where / INDEX, index_table(conds))


def index_table(conds: dict) -> pa.Table:
    entries = [(name, e) for name, c in conds.items() for e in c["entries"]]
    cols = {"condition": [name for name, _ in entries]}
    for k in ("key", "trial", "status", "epoch", "seal", "signature"):
        cols[k] = [e[k] for _, e in entries]
    cols["largest_jump"] = [e.get("largest_jump") for _, e in entries]
    cols["row"] = [e.get("row", -1) for _, e in entries]
    cols["rows"] = [e.get("rows", 0) for _, e in entries]
    return pa.Table.from_pydict({k: cols[k] for k in INDEX_SCHEMA.names}, schema=INDEX_SCHEMA)


def curve_stats(trials: pd.DataFrame) -> pd.DataFrame:
    """Mean, std and quartiles over trials per condition and epoch (condition order kept)."""
    g = trials.groupby(GROUP + ["epoch"], sort=False)
    out = g[["samples", "size"]].mean()
    out["samples"] = out["samples"].astype("int64")
    for col in ERRORS:
        out[f"{col}_mean"] = g[col].mean()
        out[f"{col}_std"] = g[col].std(ddof=1)
        out[f"{col}_q25"] = g[col].quantile(0.25)
        out[f"{col}_q75"] = g[col].quantile(0.75)
    out["n_trials"] = g["trial"].count().astype("int64")
    return out.reset_index()


def _by_condition(frame: pd.DataFrame) -> dict:
    """condition -> its rows of `frame`, in their order."""
    return {name: rows for name, rows in frame.groupby("condition", sort=False, observed=True)}


def summarize(trials: pd.DataFrame, curves: pd.DataFrame, conds: dict, paper: dict,
              fail_factor: float) -> pd.DataFrame:
    """One row per condition: final errors (mean, std over trials), the temporary increase of the
    mean absolute error during growth (epochs 1 ... T_G + 1; growth_peak), trials that diverged
    or are missing, trials that failed to bootstrap, and the paper's stated final accuracy."""
    paper_abs = paper.get("final_abs_error")
    rows, last = [], finals(trials)
    final_of, curve_of = _by_condition(last), _by_condition(curves)  # one pass, not one per condition
    for name, c in conds.items():
        final = final_of.get(name, last.iloc[:0])
        v = c["variant"] or {}
        row = {k: c["labels"][k] for k in GROUP}
        row.update(variant=v.get("label", ""), choice=v.get("choice", ""),
                   chosen=bool(v.get("chosen", False)),
                   start_size=c["spec"]["growth"]["start_size"],
                   end_size=c["spec"]["growth"]["end_size"], epochs=c["spec"]["epochs"],
                   n_trials=int(len(final)), n_diverged=len(c["diverged"]),
                   n_run_failures=len(c["missing"]),
                   diverged_epochs=",".join(str(e) for e in c["diverged"].values()))
        for col in ERRORS:
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
        row["reach"] = reach_of(c["spec"])  # the final body's; the held-out error in % of it:
        row["final_heldout_abs_error_pct_reach"] = (  # comparable across robots of any size
            100 * row["final_heldout_abs_error_mean"] / row["reach"] if row["reach"] > 0
            else np.nan)
        rows.append(row)
    import pandas as pd

    return pd.DataFrame(rows)


def stats_digest(name: str, c: dict, paper, fail_factor: float) -> str:
    """What a condition's rows of curves.parquet and summary.parquet are made of: its name,
    labels, id (spec and seed), variant, trials and their seals, the diverged and missing ones,
    the paper block, the failure factor, and the versions of the libraries that compute them
    (the code is the manifest's). The same digest, the same rows."""
    import pandas as pd

    body = [name, c["labels"], c["id"], c["variant"], sorted(c["trials"]), c["seals"],
            c["diverged"], c["missing"], paper, fail_factor, pd.__version__, np.__version__,
            pa.__version__]
    return hashlib.sha256(_compact(body).encode()).hexdigest()[:20]


def statistics(table: pa.Table, conds: dict, paper: dict, fail_factor: float,
               previous: Previous) -> tuple[pa.Table, pa.Table, dict]:
    """(curves, summary, stats) of the figure: curve_stats and summarize as tables, and per
    condition [stats_digest, first row in curves, rows, row in summary] for the manifest. A
    condition whose digest is that of the previous set keeps its rows from there (checked
    files); only the others are computed (one changed trial of 10,000: one condition of ten).
    The tables are those of computing every condition: where the computed rows' schema is not
    the previous files' (another pandas), or the previous set is unreadable, all are computed.
    `table`: every condition's trial curves (curves_table), converted to pandas where used."""
    digests = {k: stats_digest(k, c, paper, fail_factor) for k, c in conds.items()}
    kept = {k for k, d in digests.items() if previous.stats.get(k, (None,))[0] == d}
    if kept and len(kept) < len(conds):
        try:
            return _statistics_of(table, conds, paper, fail_factor, previous, digests, kept)
        except (OSError, ValueError, KeyError, IndexError, TypeError, pa.ArrowException):
            pass
    trials = table.to_pandas()
    curves = curve_stats(trials)
    curves_t = io.frame_to_table(curves)
    summary_t = io.frame_to_table(summarize(trials, curves, conds, paper, fail_factor))
    return curves_t, summary_t, _stats_record(curves_t, conds, digests)


def _statistics_of(table, conds, paper, fail_factor, previous, digests, kept):
    """statistics() with the conditions `kept` taken from the previous set."""
    computed = {k: c for k, c in conds.items() if k not in kept}
    parts = [table.slice(min(e["row"] for e in c["trials"].values()),
                         sum(e["rows"] for e in c["trials"].values()))
             for c in computed.values() if c["trials"]]  # a condition's rows are consecutive
    rows = pa.concat_tables(parts or [table.slice(0, 0)]).to_pandas()
    if set(rows["condition"]) != {k for k, c in computed.items() if c["trials"]}:
        raise ValueError("the computed conditions' rows are not theirs")
    curves = curve_stats(rows)
    new_curves = io.frame_to_table(curves)
    new_summary = io.frame_to_table(summarize(rows, curves, computed, paper, fail_factor))
    old_curves, old_summary = (previous.checked_table("curves.parquet"),
                               previous.checked_table("summary.parquet"))
    if not (new_curves.schema.equals(old_curves.schema, check_metadata=True)
            and new_summary.schema.equals(old_summary.schema, check_metadata=True)):
        raise ValueError("the computed rows' schema is not the previous files'")
    at = _stats_record(new_curves, computed, digests)
    c_parts, s_parts = [], []
    for k in conds:
        if k in kept:
            _, first, n, i = previous.stats[k]
            c_parts.append(old_curves.slice(first, n))
            s_parts.append(old_summary.slice(i, 1))
        else:
            _, first, n, i = at[k]
            c_parts.append(new_curves.slice(first, n))
            s_parts.append(new_summary.slice(i, 1))
    curves_t = pa.concat_tables(c_parts).combine_chunks()
    summary_t = pa.concat_tables(s_parts).combine_chunks()
    if summary_t.column("condition").to_pylist() != list(conds):
        raise ValueError("summary.parquet: the conditions are not the figure's")
    return curves_t, summary_t, _stats_record(curves_t, conds, digests)


def trials_file_table(table: pa.Table) -> pa.Table:
    """trials.parquet's table: what pa.Table.from_pandas(table.to_pandas(), schema=io.CURVE,
    preserve_index=False) makes of `table` (one chunk, pandas' metadata, a float NaN stored as
    null), without converting 110,000 rows twice: a table with no null and no NaN is its own
    values in one chunk, under the metadata of its first row's conversion (the metadata names
    the columns and types, not the rows); any other table is converted."""
    floats = [f.name for f in io.CURVE if pa.types.is_floating(f.type)]
    if table.num_rows and not any(table.column(n).null_count for n in table.column_names) and \
            not any(np.isnan(table.column(n).to_numpy()).any() for n in floats):
        meta = pa.Table.from_pandas(table.slice(0, 1).to_pandas(), schema=io.CURVE,
                                    preserve_index=False).schema.metadata
        return table.combine_chunks().replace_schema_metadata(meta)
    return pa.Table.from_pandas(table.to_pandas(), schema=io.CURVE, preserve_index=False)


def _stats_record(curves: pa.Table, conds: dict, digests: dict) -> dict:
    """condition -> [its stats digest, first row in `curves`, rows, row in the summary] (the
    rows of a condition are consecutive, in the order of `conds`, one summary row each)."""
    names = curves.column("condition").to_pylist()
    first, out = 0, {}
    for i, k in enumerate(conds):
        n = 0
        while first + n < len(names) and names[first + n] == k:
            n += 1
        out[k] = [digests[k], first, n, i]
        first += n
    if first != len(names):
        raise ValueError("curves: rows of no condition of the figure")
    return out


def reach_of(spec: dict) -> float:
    """The reach [m] of a condition's body at its final size (gbmodel.workspace.reach: half the
    largest distance between two hand positions within the limits)."""
    return _reach(json.dumps(spec["body"], sort_keys=True),
                  json.dumps(spec["growth"], sort_keys=True))


@lru_cache(maxsize=256)
def _reach(body_json: str, growth_json: str) -> float:
    import gbmodel
    from gbmodel import workspace

    body, g = gbmodel.make_body(json.loads(body_json)), json.loads(growth_json)
    try:  # the end body of its growth pattern (non-proportional: its own segments' sizes)
        k = gbmodel.Growth(**g).scales(body, g["end_size"])
    except (TypeError, ValueError, KeyError):
        k = np.full(body.m, float(g.get("end_size", 1.0)))
    return _reach_at(body_json, tuple(np.asarray(k, dtype=np.float64).tolist()))


@lru_cache(maxsize=256)
def _reach_at(body_json: str, factors: tuple) -> float:
    """workspace.reach of the body at per-segment `factors`: conditions that differ in their
    growth's period only end at the same body, whose workspace is sampled once (20,000
    postures: 20 ms each time)."""
    import gbmodel
    from gbmodel import workspace

    return workspace.reach(gbmodel.make_body(json.loads(body_json)), np.array(factors))


def heldout_lines(fig: str, summary: pa.Table) -> list[str]:
    """Per condition: the held-out error (the points no learner is told to reach) in mm and in
    % of the body's reach, the grid error and the trials: what a first run of one's own robot
    wants to read. `summary`: a figure's summary.parquet, read with pyarrow (a null is NaN, as
    pandas reads it)."""
    out = []
    for r in summary.to_pylist():
        r = {k: np.nan if v is None else v for k, v in r.items()}
        if not np.isfinite(r["final_heldout_abs_error_mean"]):
            out.append(f"[{fig}] {r['condition']}: no finished trial")
            continue
        out.append(f"[{fig}] {r['condition']}: held out "
                   f"{1e3 * r['final_heldout_abs_error_mean']:.1f} mm"
                   f" = {r['final_heldout_abs_error_pct_reach']:.2f} % of the reach "
                   f"({r['reach']:.3f} m); grid {1e3 * r['final_abs_error_mean']:.1f} mm; "
                   f"{r['n_trials']} trial(s) of {r['epochs']:,} epochs")
    return out


# what an aggregate's bytes depend on
CODE = ("aggregate.py", "cache.py", "io.py", "keys.py", "labels.py", "measures.py")


@lru_cache(maxsize=1)
def code_of_stage() -> str:
    """The fingerprint of this stage's code: read once per process, not once per figure."""
    here = Path(__file__).parent
    return source_fingerprint((n, (here / n).read_text()) for n in CODE)


def inputs_digest(figure: str, conds: dict, fail_factor: float, paper=None) -> str:
    """What one figure's aggregate is made of: its conditions (label, settings, trials' seals),
    the experiment's paper block (its study, claims, the paper's numbers: the summary and
    models.json carry it), the failure factor and the code of this stage. The same digest, the
    same files."""
    body = dict(figure=figure, fail_factor=fail_factor, code=code_of_stage(), paper=paper,
                conditions=[[k, c["id"], c["variant"], sorted(c["trials"]), c["missing"],
                             c["seals"]] for k, c in conds.items()])
    return hashlib.sha256(_compact(body).encode()).hexdigest()[:20]  # json's C encoder


def aggregate_figure(cfg: DictConfig, fig: str) -> tuple[list[str], bool]:
    """Aggregate one figure, unless its aggregate is already made of the same inputs; (problems,
    whether it was rebuilt). Only the trials whose files changed since the current aggregate are
    read (Previous). The figure's files are replaced as one set (pipeline.io.new_set); a damaged
    plan record, or no trial at all where the aggregate had some, leaves it as it was."""
    folder = Path(cfg.paths.aggregate) / io.safe_name("figure", fig)
    previous = Previous(folder)
    try:
        conds, paper, problems = load_trials(cfg.paths.cache, fig, previous)
    except io.DamagedFile as err:
        return [f"{err}; the figure's aggregate is left as it was"], False
    digest = inputs_digest(fig, conds, cfg.aggregate.fail_factor, paper)
    try:
        old = io.read_json(folder / "manifest.json")
    except (OSError, ValueError):
        old = {}
    if old.get("inputs") == digest and previous.where is not None:
        refresh_index(conds, previous)
        return problems, False
    if not any(c["trials"] for c in conds.values()) and old.get("trials"):
        return problems + ["no trial of the figure is readable; its aggregate is left as it "
                           "was"], False
    try:
        table = curves_table(conds, previous)
        model_of, sums = models(conds, previous)
    except (OSError, ValueError, KeyError, IndexError):  # the previous aggregate is damaged
        previous = Previous()
        for c in conds.values():
            _fill(cfg.paths.cache, c["entries"])
        table, (model_of, sums) = curves_table(conds, previous), models(conds, previous)
    curves, summary, stats = statistics(table, conds, paper, cfg.aggregate.fail_factor,
                                        previous)
    for c, n in zip(summary.column("condition").to_pylist(),
                    summary.column("n_trials").to_pylist()):
        if n == 0:
            print(f"note: [{fig}] {c}: every trial diverged or failed; the report marks it "
                  "diverged", file=sys.stderr)
    with io.new_set(folder) as tmp:
        sha256 = {name: io.write_table(tmp / name, t)
                  for name, t in (("trials.parquet", trials_file_table(table)),
                                  ("curves.parquet", curves), ("summary.parquet", summary))}
        io.write_text(tmp / "models.json", models_text(fig, paper, model_of))
        io.write_table(tmp / INDEX, index_table(conds))
        io.write_json(tmp / "manifest.json", dict(
            figure=fig, inputs=digest, code=code_of_stage(), trials=table.num_rows,
            models={k: [conds[k]["id"], sums[k]] for k in model_of}, stats=stats,
            sha256=sha256))
    log.info("[%s] %d conditions, %d trial curves -> %s", fig, summary.num_rows,
             sum(len(c["trials"]) for c in conds.values()), folder)
    return problems, True


def named_figures(cfg: DictConfig, explicit: bool, known: list[str], folder,
                  state: str) -> list[str] | None:
    """The figures the command line names (experiments=, or the one figure= / experiment=
    names), or None where it names none; one that is not among `known` (the figures `state`,
    simulated or aggregated, under `folder`) is a FileNotFoundError (one line)."""
    if cfg.get("experiments"):
        wanted = list(cfg.experiments)  # an experiment's figure is its name (tested)
    elif explicit:
        wanted = [cfg.figure]
    else:
        return None
    missing = [f for f in wanted if f not in known]
    if missing:
        raise FileNotFoundError(f"figure={missing[0]}: not {state} under {folder} "
                                f"({state}: {', '.join(known) or 'none'})")
    return wanted


def selected_figures(cfg: DictConfig, explicit: bool) -> list[str]:
    """The figures a stage works on: every simulated one, or (figure= / experiment= /
    experiments= on the command line) those named; an unknown one is a FileNotFoundError."""
    known = cache.figures(cfg.paths.cache)
    if not known:
        raise FileNotFoundError(f"no simulated figure under {cfg.paths.cache}: "
                                "run pipeline.simulate first")
    named = named_figures(cfg, explicit, known, cfg.paths.cache, "simulated")
    return known if named is None else named


def aggregate(cfg: DictConfig, explicit: bool = False) -> list[str]:
    """Aggregate the selected figures (selected_figures) whose inputs changed; return the
    problems found."""
    problems, rebuilt, figures = [], 0, selected_figures(cfg, explicit)
    for fig in figures:
        found, new = aggregate_figure(cfg, fig)
        problems += [f"[{fig}] {p}" for p in found]
        rebuilt += new
        if not gc.isenabled():  # the command (one_shot): each figure's cycles freed before the next
            gc.collect()
        show_heldout(Path(cfg.paths.aggregate) / io.safe_name("figure", fig), fig,
                     explicit or len(figures) == 1)
    log.info("aggregate: %d of %d figure(s) rebuilt, the others unchanged", rebuilt, len(figures))
    return problems


SHOWN_CONDITIONS = 8  # a figure of more conditions (make smoke's) is not listed unless named


def show_heldout(folder: Path, fig: str, named: bool) -> None:
    """Log heldout_lines for a figure named on the command line (or the only one), or one of at
    most SHOWN_CONDITIONS conditions."""
    try:  # a pyarrow table: a figure left as it was loads no pandas
        summary = io.read_table(io.set_of(folder) / "summary.parquet")
    except (OSError, ValueError):
        return  # nothing aggregated (a problem already named)
    if "final_heldout_abs_error_pct_reach" not in summary.column_names or not (
            named or summary.num_rows <= SHOWN_CONDITIONS):
        return
    for line in heldout_lines(fig, summary):
        log.info("%s", line)


def names_a_figure(overrides: list[str]) -> bool:
    return any(o.lstrip("+").startswith(("figure=", "experiment=")) for o in overrides)


def one_shot() -> None:
    """Settings for the command's one process (not for the API: a caller's process is its own).
    Arrow's buffers come from the C library's allocator: with Arrow's default (mimalloc) the
    writes of a 10,000-trial set cost 0.1 to 0.9 s of system time more, varying from run to run
    (ARROW_DEFAULT_MEMORY_POOL, if set, wins). Python's cyclic collector, off since the imports
    began, runs once per figure (aggregate) instead of about 300 times over the objects a
    rebuild holds (0.1 s): what the imports made is frozen out of every collection."""
    import pyarrow as pa

    if "ARROW_DEFAULT_MEMORY_POOL" not in os.environ:
        pa.set_memory_pool(pa.system_memory_pool())
    gc.freeze()


def run(cfg: DictConfig) -> int:
    """aggregate() for the command line: a warning per problem, exit status 1 if any."""
    one_shot()
    problems = aggregate(cfg, names_a_figure(cli.hydra_run()[0]))
    for p in problems:
        print(f"warning: {p}", file=sys.stderr)
    return 1 if problems else 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
