"""The aggregate's set as trials enter it: each trial read from the cache once, or taken from the
figure's previous set where its files did not change (Previous), and the models.json text."""
from __future__ import annotations

import hashlib
import json
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np
import pyarrow as pa

from . import cache, io
from .fingerprint import source_fingerprint
from .labels import condition_labels

# what an aggregate's bytes depend on
CODE = ("aggregate.py", "aggregate_set.py", "aggregate_stats.py", "cache.py", "io.py", "keys.py",
        "labels.py", "measures.py")
INDEX = "index.parquet"  # per trial of the aggregate: what was read, to reuse it next time
_S, _I = pa.string(), pa.int64()
INDEX_SCHEMA = pa.schema([("key", _S), ("condition", _S), ("trial", _I), ("status", _S),
                          ("epoch", _I), ("seal", _S), ("signature", _S),
                          ("largest_jump", pa.float64()), ("row", _I), ("rows", _I)])
MODELS_HEAD = '{"conditions":{'
_DECODER = json.JSONDecoder()


def figure_conditions(cache_dir, figure: str) -> tuple[list[dict], dict, list[str]]:
    """The figure's conditions labelled by what differs between them: variants in their order,
    then growing bodies by period, then references by size (a stable sort)."""
    conds, paper, problems = cache.figure_conditions(cache_dir, figure)
    order = {}
    for c in conds:
        c["_variant_index"] = order.setdefault((c.get("variant") or {}).get("label"), len(order))
    conds = sorted(conds, key=lambda c: (c["_variant_index"], c["growth"] == "none",
                                         c["growth_period"], c["spec"]["growth"]["end_size"]))
    for c, label in zip(conds, condition_labels(conds)):
        c["label"] = label
    return conds, paper, problems


@lru_cache(maxsize=1)
def code_of_stage() -> str:
    here = Path(__file__).parent
    return source_fingerprint((n, (here / n).read_text()) for n in CODE)


def _checksum(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _compact(obj) -> str:  # json's C encoder
    return json.dumps(obj, sort_keys=True, separators=(",", ":"))


class Previous:
    """The figure's current aggregate, if made by this stage's code: a trial whose files still
    have the signature it records is taken from here, not read again; if unreadable, nothing."""

    def __init__(self, folder: Path | None = None):
        self.index, self.where = {}, None
        self.finished = {}  # condition -> its finished trials (their indices)
        self.lines = {}  # condition -> (id, checksum of its models.json line)
        self.stats = {}  # condition -> (stats_digest, first row in curves, rows, row in summary)
        self._sums = {}  # file -> its SHA-256 (the manifest's)
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
            lines = {k: tuple(v) for k, v in manifest.get("models", {}).items()}
            stats = {k: tuple(v) for k, v in manifest.get("stats", {}).items()}
            sums = dict(manifest.get("sha256", {}))
        except (OSError, ValueError, TypeError):
            return
        self.index, self.where = {r["key"]: r for r in rows}, where
        self.lines, self.stats, self._sums = lines, stats, sums
        for r in rows:
            if r["status"] != "diverged":
                self.finished.setdefault(r["condition"], []).append(str(r["trial"]))

    @cached_property
    def trials(self) -> pa.Table:
        # the curves' own columns only: the labels are set again per condition, and their
        # strings cost nine tenths of reading the file (0.08 of 0.09 s, 10,000 trials)
        return self.checked_table("trials.parquet", io.TRIAL_CURVE)

    def checked_table(self, name: str, schema: pa.Schema | None = None) -> pa.Table:
        """A file of the set, if its bytes are those the manifest recorded (else ValueError)."""
        data = (self.where / name).read_bytes()
        if hashlib.sha256(data).hexdigest() != self._sums.get(name):
            raise ValueError(f"{name}: not the file the manifest recorded")
        return io.parse_table(data, self.where / name, schema,
                              None if schema is None else schema.names)

    @cached_property
    def _texts(self) -> dict[str, str]:
        return model_lines((self.where / "models.json").read_text())

    def text(self, condition: str) -> str:
        """The condition's line of models.json, checked against the manifest (else ValueError)."""
        text = self._texts.get(condition)
        if text is None or _checksum(text) != self.lines.get(condition, (None, None))[1]:
            raise ValueError(f"models.json: the line of {condition!r} is damaged")
        return text

    def pieces(self, condition: str) -> dict[str, str]:
        """trial -> its model's JSON text in text(condition), cut where json's decoder ends it,
        not encoded again (ValueError if the line is not model_line's)."""
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
        return out


def load_trials(cache_dir, figure: str, previous: Previous | None = None):
    """(conditions by label, paper, problems): each condition's trial entries (seal, status, the
    curve table or its rows in `previous`), each read once or taken from `previous`."""
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
            if not isinstance(entry, dict):
                c["missing"].append(i)
                problems.append(f"{name} trial {i}: "
                                f"{entry or 'not computed (run pipeline.simulate)'}")
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


def curves_table(conds: dict, previous: Previous) -> pa.Table:
    """Every finished trial's curve in io.CURVE, with its labels; each entry's rows recorded."""
    parts, row = [], 0
    for c in conds.values():
        pieces, counts, trials = [], [], []
        for e in c["trials"].values():
            if "table" in e:
                piece = e["table"].select(io.TRIAL_CURVE.names)
            else:  # consecutive rows of the previous aggregate are taken as one slice
                piece = ("slice", e["row"], e["rows"])
                if pieces and isinstance(pieces[-1], tuple) and sum(pieces[-1][1:]) == e["row"]:
                    _, first, n = pieces.pop()
                    piece = ("slice", first, n + e["rows"])
            pieces.append(piece)
            e["row"], e["rows"] = row, len(e["table"]) if "table" in e else e["rows"]
            row += e["rows"]
            counts.append(e["rows"])
            trials.append(e["trial"])
        if not pieces:
            continue
        old = previous.trials.select(io.TRIAL_CURVE.names) if any(
            isinstance(p, tuple) for p in pieces) else None
        body = pa.concat_tables([old.slice(p[1], p[2]) if isinstance(p, tuple) else p
                                 for p in pieces])
        same = pa.array(np.zeros(len(body), dtype=np.int64))  # each label n times: a take
        # (pa.repeat of a string scalar cost 19 ms per 11,000 rows: 1 s of a 10,000-trial figure)
        cols = {k: pa.array([v], io.CURVE.field(k).type).take(same)
                for k, v in c["labels"].items()}
        cols["trial"] = pa.array(np.repeat(np.asarray(trials, dtype=np.int64), counts))
        cols.update({k: body.column(k) for k in io.TRIAL_CURVE.names})
        parts.append(pa.Table.from_pydict({k: cols[k] for k in io.CURVE_COLUMNS},
                                          schema=io.CURVE))
    return pa.concat_tables(parts) if parts else io.CURVE.empty_table()


def models(conds: dict, previous: Previous) -> tuple[dict[str, str], dict[str, str]]:
    """Per condition its model_line and checksum: a condition whose id and trials are the previous
    aggregate's, none read again, keeps both (not hashed again); in one that changed, only the
    models read are encoded (the others: Previous.pieces)."""
    out, sums = {}, {}
    for k, c in conds.items():
        before, kept = previous.lines.get(k), [e for e in c["trials"].values() if "model" not in e]
        if (before is not None and before[0] == c["id"] and len(kept) == len(c["trials"])
                and sorted(c["trials"]) == sorted(previous.finished.get(k, []))):
            out[k], sums[k] = previous.text(k), before[1]
            continue
        kept = previous.pieces(k) if kept else {}
        out[k] = model_line(c["spec"], c["id"], {
            i: _compact(e["model"]) if "model" in e else kept[i] for i, e in c["trials"].items()})
        sums[k] = _checksum(out[k])
    return out, sums


def model_line(spec: dict, cid: str, trials: dict[str, str]) -> str:
    """_compact({"spec": spec, "id": cid, "trials": trials}), each trial's model already encoded."""
    models = ",".join(f"{json.dumps(i)}:{trials[i]}" for i in sorted(trials))
    return f'{{"id":{_compact(cid)},"spec":{_compact(spec)},"trials":{{{models}}}}}'


def model_lines(text: str) -> dict[str, str]:
    """Condition -> its line of a models.json text (models_text), as written."""
    lines, out = text.split("\n"), {}
    for line in lines[1:-2] if lines[0] == MODELS_HEAD else ():
        if line:
            name, end = _DECODER.raw_decode(line)
            out[name] = line[end + 1:].rstrip(",")
    return out


def models_text(fig: str, paper, texts: dict[str, str]) -> str:
    """models.json: compact JSON with sorted keys, each condition on a line of its own."""
    body = ",\n".join(f"{json.dumps(k)}:{texts[k]}" for k in sorted(texts))
    return (f"{MODELS_HEAD}\n{body}\n}},\"figure\":{json.dumps(fig)},"
            f"\"paper\":{_compact(paper)}}}\n")


def refresh_index(conds: dict, previous: Previous) -> None:
    """Inputs unchanged, trials rewritten with the same seals: their signatures into the index."""
    fresh = [e for c in conds.values() for e in c["entries"] if "table" in e]
    for e in fresh:
        known = previous.index.get(e["key"])
        if known is None or known["seal"] != e["seal"]:
            return
        e["row"], e["rows"] = known["row"], known["rows"]
    if fresh:
        io.write_table(previous.where / INDEX, index_table(conds))


def index_table(conds: dict) -> pa.Table:
    entries = [dict(e, condition=name) for name, c in conds.items() for e in c["entries"]]
    fill = dict(largest_jump=None, row=-1, rows=0)
    return pa.Table.from_pydict({k: [e[k] if k not in fill else e.get(k, fill[k]) for e in entries]
                                 for k in INDEX_SCHEMA.names}, schema=INDEX_SCHEMA)
