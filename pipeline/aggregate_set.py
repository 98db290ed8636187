"""The aggregate's set of files as trials enter it: each trial read from the cache once, or, where
its files did not change, taken from the figure's previous set (Previous: index.parquet, the
manifest's checksums), and the models.json text of each condition (pipeline/aggregate.py writes
the set; pipeline/aggregate_stats.py computes its curves and summary)."""
from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from pathlib import Path

import numpy as np
import pyarrow as pa

from . import cache, io
from .fingerprint import source_fingerprint
from .labels import condition_labels


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


# what an aggregate's bytes depend on
CODE = ("aggregate.py", "aggregate_set.py", "aggregate_stats.py", "cache.py", "io.py", "keys.py", "labels.py", "measures.py")


@lru_cache(maxsize=1)
def code_of_stage() -> str:
    """The fingerprint of this stage's code: read once per process, not once per figure."""
    here = Path(__file__).parent
    return source_fingerprint((n, (here / n).read_text()) for n in CODE)



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
