"""``fringekit sweep``: a grid or list of cases over any config key, run on Dask.

A sweep file is TOML::

    base = "reference"          # a built-in case or a config file (relative to this file)
    name = "thickness"          # optional; default: the file name
    [set]                       # optional: overrides applied to every case
    "optics.pixels" = 128
    [grid]                      # the cartesian product of these values ...
    "sheet.thickness_mm" = [2.0, 3.0, 4.0]
    "indenter.load_N" = [[2.0], [4.0], [8.0]]
    # ... or an explicit list instead of [grid]:
    # [[case]]
    # "sheet.E_MPa" = 3.0

Every case runs the ``predict`` pipeline into ``<out>/cases/<id>/``: it is written to
``<id>.part/`` and renamed when it has finished, so a killed sweep leaves only finished
cases behind, and a re-run skips them (``result.json`` holds the case's effective config;
a case whose config changed is run again). Cases run in parallel on a Dask cluster: a
local one by default (one single-threaded worker process per core, so the direct solver
of one case does not fight another for the cores), or ``scheduler`` for an existing one.
The table ``results.csv`` (one row per case: the swept values, status, max fringe order,
indenter force, depth and contact radius, time) and ``plots/`` are rebuilt from the case
folders at the end of every run.
"""

from __future__ import annotations

import copy
import csv
import hashlib
import io
import itertools
import json
import os
import re
import shutil
import time
from pathlib import Path

from fringekit._cluster import run_tasks
from fringekit.config.files import ConfigError, apply_overrides, load_config, tomllib
from fringekit.meshes import default_cache_dir
from fringekit.output.figures import sweep_plots
from fringekit.output.folders import atomic_write, claim_output
from fringekit.prediction.pipeline import PredictError, run_predict

__all__ = ["load_sweep", "case_id", "expand_cases", "run_sweep", "collect_results"]

_SWEEP_KEYS = {"base", "name", "set", "grid", "case"}


def load_sweep(path: str | os.PathLike) -> dict:
    """Read and check a sweep file; returns ``{"name", "base_config", "cases": [...]}``."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"sweep file {str(path)!r} does not exist")
    try:
        d = tomllib.loads(path.read_text(encoding="utf-8-sig"))  # an editor's BOM is fine
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    unknown = sorted(set(d) - _SWEEP_KEYS)
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r} in {path}; allowed: {sorted(_SWEEP_KEYS)}")
    base_name = d.get("base", "reference")
    base_path = path.parent / base_name
    base = load_config(base_path if base_path.is_file() else base_name)
    if "set" in d:
        base = apply_overrides(base, d["set"])
    if ("grid" in d) == ("case" in d):
        raise ConfigError(f"{path}: give either a [grid] table or [[case]] tables (one of them)")
    if "grid" in d:
        grid = d["grid"]
        if not grid or not all(isinstance(v, list) and v for v in grid.values()):
            raise ConfigError(f"{path}: every [grid] key needs a non-empty list of values")
        keys = list(grid)
        overrides = [
            dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grid.values())
        ]
    else:
        overrides = [dict(c) for c in d["case"]]
    name = d.get("name", path.stem)
    if (
        not isinstance(name, str)
        or not name.strip()
        or any(c in name for c in "/\\")
        or name.strip() in (".", "..")
    ):
        raise ConfigError(
            f"{path}: name = {json.dumps(name)} is not allowed; give a plain folder name "
            "(no path separators, not . or ..): the default output folder is "
            "fringekit-out/<name>"
        )
    return {"name": name, "base_config": base, "cases": expand_cases(base, overrides)}


def _case_text(over: dict) -> str:
    return ",".join(f"{k}={json.dumps(v)}" for k, v in over.items())


def case_id(over: dict) -> str:
    """A case's folder name: the first 60 characters of its overrides that are safe in a
    file name, and 64 bits of their sha256 (a million cases collide with a chance of
    3e-8; the 32 bits used before collided about 100 times in such a grid)."""
    text = _case_text(over)
    short = re.sub(r"[^A-Za-z0-9_.=,-]+", "", text.replace(" ", ""))[:60]
    return f"{short}-{hashlib.sha256(text.encode()).hexdigest()[:16]}"


def expand_cases(base: dict, overrides: list[dict]) -> list[dict]:
    """One ``{"id", "overrides", "config"}`` per case, every config checked up front.
    A case repeats an earlier one when its overrides are the same (not its id)."""
    cases, seen, texts = [], set(), set()
    for k, over in enumerate(overrides):
        try:
            cfg = apply_overrides(base, over)
        except ConfigError as exc:
            raise ConfigError(f"case {k} ({_case_text(over)}): {exc}") from None
        text, cid = _case_text(over), case_id(over)
        if text in texts:
            raise ConfigError(f"case {k} ({_case_text(over)}) repeats an earlier case")
        if cid in seen:  # pragma: no cover - 64 bits: about 3e-8 in a million cases
            raise ConfigError(
                f"case {k} ({_case_text(over)}) has the folder name of an earlier case ({cid})"
            )
        seen.add(cid)
        texts.add(text)
        cfg = copy.deepcopy(cfg)
        cfg["case"] = cid
        cases.append({"id": cid, "overrides": over, "config": cfg})
    return cases


def _run_case(case: dict, out_root: str, cache_dir: str | None) -> dict:
    """Run one case into ``cases/<id>.part`` and rename it when done (runs on a worker)."""
    final = Path(out_root) / "cases" / case["id"]
    part = final.with_name(final.name + ".part")
    shutil.rmtree(part, ignore_errors=True)
    t0 = time.perf_counter()
    result = {"id": case["id"], "overrides": case["overrides"], "config": case["config"]}
    try:
        summary = run_predict(case["config"], part, cache_dir=cache_dir, progress=False)
        result.update(status="ok", summary=_brief(summary))
    except (PredictError, ValueError) as exc:
        result.update(status="failed", error=str(exc))
        summary_file = part / "summary.json"
        if summary_file.is_file():
            result["summary"] = _brief(json.loads(summary_file.read_text()))
    result["time_s"] = time.perf_counter() - t0
    part.mkdir(parents=True, exist_ok=True)
    (part / "result.json").write_text(json.dumps(result, indent=2, default=float))
    shutil.rmtree(final, ignore_errors=True)
    os.replace(part, final)  # the case appears whole or not at all
    return result


def _brief(summary: dict) -> dict:
    return {
        "max_fringe_order": summary.get("max_fringe_order"),
        "indenters": summary.get("indenters"),
        "times_s": summary.get("times_s"),
        "solution_from_cache": summary.get("model", {}).get("solution_from_cache"),
    }


def _finished(out: Path, case: dict) -> bool:
    f = out / "cases" / case["id"] / "result.json"
    if not f.is_file():
        return False
    try:
        return json.loads(f.read_text())["config"] == case["config"]
    except (OSError, ValueError, KeyError):
        return False


def run_sweep(
    sweep: dict,
    out: str | os.PathLike,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    cache_dir: str | os.PathLike | None = None,
    progress: bool = True,
    echo=print,
    inputs=(),
) -> dict:
    """Run the sweep's unfinished cases on Dask, then rebuild the table and plots
    (``inputs``: the sweep file, never inside ``out``)."""
    out = Path(out)
    with claim_output(out, command="sweep", inputs=inputs, resume=True):
        (out / "cases").mkdir(parents=True, exist_ok=True)
        cache = str(cache_dir or default_cache_dir())
        todo = [c for c in sweep["cases"] if not _finished(out, c)]
        done_before = len(sweep["cases"]) - len(todo)
        say = echo if progress else (lambda s: None)
        say(f"sweep {sweep['name']}: {len(sweep['cases'])} cases, {done_before} already finished")
        t0 = time.perf_counter()

        def report(res: dict) -> None:
            if res["status"] != "ok":
                say(f"case {res['id']} failed: {res.get('error')}")

        run_tasks(
            _run_case,
            todo,
            [f"case-{c['id']}" for c in todo],
            str(out.resolve()),
            cache,
            scheduler=scheduler,
            workers=workers,
            progress=progress,
            desc="cases",
            unit="case",
            on_result=report,
        )
        table = collect_results(sweep, out)
    return {
        "cases": len(sweep["cases"]),
        "run": len(todo),
        "skipped": done_before,
        "failed": sum(r["status"] != "ok" for r in table),
        "time_s": time.perf_counter() - t0,
        "table": str(out / "results.csv"),
    }


def _cell(v):
    return json.dumps(v) if isinstance(v, list) else v


def collect_results(sweep: dict, out: str | os.PathLike) -> list[dict]:
    """Rebuild ``results.csv``, ``results.json`` and ``plots/`` from the finished cases."""
    out = Path(out)
    keys = list(dict.fromkeys(k for c in sweep["cases"] for k in c["overrides"]))
    rows = []
    for c in sweep["cases"]:
        f = out / "cases" / c["id"] / "result.json"
        if not f.is_file():
            continue
        res = json.loads(f.read_text())
        s = res.get("summary") or {}
        ind = (s.get("indenters") or [{}])[0]
        rows.append(
            {
                "id": c["id"],
                **{k: _cell(c["overrides"].get(k)) for k in keys},
                "status": res["status"],
                "max_fringe_order": s.get("max_fringe_order"),
                "force_z_N": (ind.get("force_N") or [None] * 3)[2],
                "depth_mm": ind.get("depth_mm"),
                "contact_radius_mm": ind.get("contact_radius_mm"),
                "time_s": res.get("time_s"),
                "error": res.get("error", ""),
            }
        )
    fields = [
        "id",
        *keys,
        "status",
        "max_fringe_order",
        "force_z_N",
        "depth_mm",
        "contact_radius_mm",
        "time_s",
        "error",
    ]
    table = io.StringIO()
    w = csv.DictWriter(table, fieldnames=fields)
    w.writeheader()
    w.writerows(rows)
    atomic_write(out / "results.csv", table.getvalue())
    atomic_write(out / "results.json", json.dumps(rows, indent=2, default=float))
    sweep_plots(rows, keys, out / "plots")
    return rows
