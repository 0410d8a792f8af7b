"""Builds `benchmarks/results/README.md`, the index of the committed result files.

    python tools/results_index.py           # rewrite the index
    python tools/results_index.py --check   # exit 1 if the index is out of date (tests/test_docs.py)
    python tools/results_index.py --sort    # first `git mv` result files left at the top level into
                                            # their kind's folder (by file name), then rewrite

One row per run: the files that share a stem (`X.json`, `X.log`, `X.png`, `X.md`, `X-compile-*.txt`,
...). What, device, commit and date come from the JSON where it records them, else from the
Markdown's title and the file name. The command is the one the run recorded (a JSON `command`, or
the first script invocation quoted in its Markdown); for `benchmarks/throughput.py` JSON files,
which do not record theirs, it is rebuilt from the recorded settings and marked `≈`.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
INDEX = RESULTS / "README.md"

# Folder -> (file-name prefixes that belong there, what the folder holds). `--sort` files new
# results by these prefixes (first match wins).
KINDS: dict[str, tuple[tuple[str, ...], str]] = {
    "throughput": (
        ("throughput-", "ccd-slots-", "per-scene-rows-", "multi-gpu-"),
        "env steps per second (`benchmarks/throughput.py`), plots, buffer and adapter timings",
    ),
    "compile": (
        ("compile-", "anatomy-", "hlo-", "native-", "substep-loop-"),
        "compile-time experiments: what the step program costs to lower, compile and load",
    ),
    "experts": (("experts-",), "scripted experts against the reference's (`benchmarks/experts.py`)"),
    "fidelity": (
        ("free-run-", "parity-suite-", "engine-compare-", "contact-compare-", "grasp-step-compare-"),
        "whole-episode tables, parity-suite logs and engine comparisons (`docs/fidelity.md`)",
    ),
    "overflow": (
        ("overflow-", "stress-"),
        "Warp's dropped-buffer flags and constraint rows per task (`benchmarks/stress_buffers.py`)",
    ),
    "profile": (("profile-", "gpu-probes-"), "where the step's time goes (`benchmarks/profile_*.py`)"),
    "determinism": (("determinism-",), "run-to-run repeatability on the GPU (`benchmarks/determinism.py`)"),
    "reference": (("reference-",), "measurements of the reference itself (metaworld 3.1.1)"),
    "train": (("train-",), "multi-task PPO runs (`examples/train_mt_ppo.py`, `docs/training.md`)"),
}

_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")
_COMMIT = re.compile(r"(?:^|-)((?=[0-9a-f]*\d)[0-9a-f]{7})(?=-)")
_DEVICES = {"NVIDIA_H100_80GB_HBM3": "NVIDIA H100 80GB HBM3", "NVIDIA_H200": "NVIDIA H200", "cpu": "CPU"}
# A script invocation of this repository, with an optional interpreter: quoted anywhere in a
# report's opening paragraph, or unquoted in its title.
_SCRIPT = r"(?:\S*python3? )?(?:benchmarks|tools|examples)/\w+\.py"
_MD_COMMAND = re.compile(rf"`({_SCRIPT}(?: [^`]*)?)`")
_TITLE_COMMAND = re.compile(rf"({_SCRIPT}(?: [^,`]*)?)")


def stem(name: str) -> str:
    """The run a file belongs to: its name up to its date, else without its extension."""
    match = _DATE.search(name)
    if match:
        return name[: match.end()]
    return name.split(".")[0]


def _device(name: str, data: dict) -> str:
    if data.get("device"):
        return "CPU" if data["device"] == "cpu" else str(data["device"])
    for token, device in _DEVICES.items():
        if f"-{token}-" in name:
            return device
    return "—"


def _throughput_rows(data: dict) -> list[dict]:
    rows = data.get("results")
    if not isinstance(rows, list) or not rows:
        return []
    if not all(
        isinstance(r, dict) and {"benchmark", "steps_per_rollout", "env_steps_per_s"} <= r.keys()
        for r in rows
    ):
        return []
    return rows


def _warmed_up(data: dict, rows: list[dict]) -> bool:
    """Whether the timed rollouts came after an untimed one: older files say so in the header,
    newer ones give that rollout's seconds in each row (`first_rollout_s`, `warmup_rollout_s`)."""
    if data.get("warmup_rollout") in (True, "True"):
        return True
    return all(r.get("first_rollout_s") is not None or r.get("warmup_rollout_s") is not None for r in rows)


def _rate(row: dict) -> str:
    if row["env_steps_per_s"] is None:
        return f"refused ({row.get('refused') or 'no figure'})"
    return f"{row['env_steps_per_s']:,.0f}"


def _what(files: list[Path], data: dict) -> str:
    if rows := _throughput_rows(data):
        parts = []
        for benchmark in dict.fromkeys(r["benchmark"] for r in rows):
            mine = [r for r in rows if r["benchmark"] == benchmark]
            rates = ", ".join(f"{r['num_envs']:,} envs {_rate(r)}" for r in mine)
            parts.append(
                f"{benchmark}{' physics only' if mine[0].get('mode') == 'physics only' else ''}: {rates}"
            )
        for ref in data.get("reference") or []:
            parts.append(
                f"reference {ref['benchmark']}: run failed"
                if "error" in ref
                else f"reference {ref['benchmark']} ({ref['num_envs']} envs): {ref['env_steps_per_s']:,.0f}"
            )
        timed = "timed after a warm-up rollout" if _warmed_up(data, rows) else "the first rollout timed"
        protocol = rows[0].get("protocol") or ""
        # A staggered row's label says more than its rollout length: episodes start anywhere.
        window = (
            protocol.removeprefix("labelled: ")
            if "staggered" in protocol
            else f"{rows[0]['steps_per_rollout']}-step rollouts"
        )
        return f"env steps/s, {window}, {timed}: " + "; ".join(parts)
    if "mean_success_rate" in data and "set" in data:
        return (
            f"{data['set']} scripted experts: mean success {data['mean_success_rate']:.3f} "
            f"(reference {data['reference_mean_success_rate']:.3f})"
        )
    if "eval_success" in data and data.get("runs"):
        config = data["runs"][0]["config"]
        task_set = config["task_set"] if isinstance(config["task_set"], str) else ",".join(config["task_set"])
        scores = ", ".join(f"{s:.3f}" for s in data["eval_success"])
        return f"PPO on {task_set}, {config['envs_per_task']:,} envs per task: evaluation success {scores}"
    if "mean_success_rate" in data and "what" in data:
        return f"{data['what']}: mean success {data['mean_success_rate']:.3f}"
    if "env_steps_per_s" in data and isinstance(data["env_steps_per_s"], dict):
        variants = ", ".join(f"{k} {v:,.0f}" for k, v in data["env_steps_per_s"].items())
        return f"{data.get('set', '')} {data.get('num_envs', 0):,} envs, env steps/s: {variants}"
    md = next((f for f in files if f.suffix == ".md"), None)
    if md is not None:
        return md.read_text().splitlines()[0].lstrip("#").strip()
    if all(f.suffix == ".png" for f in files):
        return "plot"
    kinds = sorted({f.suffix.lstrip(".") for f in files})
    return f"{stem(files[0].name)} ({', '.join(kinds)})"


def _rebuilt_throughput_command(data: dict) -> str:
    rows = _throughput_rows(data)
    sets = list(dict.fromkeys(r["benchmark"] for r in rows))
    batches = list(dict.fromkeys(r["num_envs"] for r in rows))
    steps = rows[0]["steps_per_rollout"]
    parts = ["python benchmarks/throughput.py", "--sets", *sets, "--batch", *map(str, batches)]
    parts += ["--steps", str(steps), "--repeats", str(len(rows[0].get("rollout_s") or [1]))]
    if rows[0].get("mode") == "physics only":
        parts.append("--physics-only")
    if data.get("warmup_rollout") in (False, "False"):
        parts.append("--no-warmup")
    if data.get("unroll_substeps") in (False, "False"):
        parts.append("--substep-loop")
    if data.get("share_traces") in (True, "True"):
        parts.append("--share-traces")
    if data.get("graph_mode") not in (None, "None"):
        parts += ["--graph-mode", str(data["graph_mode"])]
    if data.get("jax_cache") not in (None, "None"):
        parts += ["--jax-cache", str(data["jax_cache"])]
    if data.get("reference"):
        parts += ["--vs-reference", "PYTHON"]
    if data.get("adapter"):
        parts.append("--adapter")
    buffers = [f"{k}={data[k]}" for k in ("constraints_per_env", "ccd_pairs_per_env") if k in data]
    return "≈ " + " ".join(parts) + (f" ({', '.join(buffers)})" if buffers else "")


def _rebuilt_command(data: dict) -> str | None:
    """For result files that do not record their command: one rebuilt from what they record."""
    if _throughput_rows(data):
        return _rebuilt_throughput_command(data)
    if "mean_success_rate" in data and "set" in data:
        return (
            f"≈ python benchmarks/experts.py --set {data['set']} --seed {data['seed']} "
            f"--goals {data['goals']} --episodes {data['episodes_per_task']}"
        )
    if "eval_success" in data and data.get("runs"):
        config = dict(data["runs"][0]["config"])
        flags = {"envs_per_task": "--envs-per-task", "unroll": "--unroll", "minibatches": "--minibatches"}
        flags |= {"epochs": "--epochs", "learning_rate": "--lr"}
        parts = ["≈ python examples/train_mt_ppo.py"] + [
            f"{flag} {config.pop(k)}" for k, flag in flags.items()
        ]
        other = [
            f"{k}={config[k]}" for k in ("architecture", "multi_head", "staggered_starts") if k in config
        ]
        return " ".join(parts) + (f" ({', '.join(other)})" if other else "")
    return None


def _opening(md: Path) -> tuple[str, str]:
    """A report's title and the first two lines of its first paragraph after the title."""
    lines = md.read_text().splitlines()
    paragraph: list[str] = []
    for line in lines[1:]:
        if line.strip():
            paragraph.append(line)
        elif paragraph:
            break
    return lines[0], " ".join(paragraph[:2])


def _command(files: list[Path], data: dict) -> str:
    if data.get("command"):
        return str(data["command"])
    for md in (f for f in files if f.suffix == ".md"):
        title, paragraph = _opening(md)
        match = _MD_COMMAND.search(title) or _TITLE_COMMAND.search(title) or _MD_COMMAND.search(paragraph)
        if match:
            return match.group(1).strip()
    return _rebuilt_command(data) or "not recorded"


def _commit(name: str, files: list[Path], data: dict) -> str:
    if data.get("commit"):  # "a+b" where `--combine --across-commits` joined runs of two commits
        return "+".join(commit[:7] for commit in str(data["commit"]).split("+"))
    match = _COMMIT.search(name)
    if match:
        return match.group(1)
    for md in (f for f in files if f.suffix == ".md"):
        found = re.search(r"commit `?([0-9a-f]{7,40})\b", md.read_text())
        if found:
            return found.group(1)[:7]
    return "—"


def _date(name: str, data: dict) -> str:
    if data.get("date"):
        return str(data["date"])[:10]
    match = _DATE.search(name)
    return match.group(0) if match else "—"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def runs(folder: Path) -> list[tuple[str, list[Path]]]:
    groups: dict[str, list[Path]] = {}
    for path in sorted(p for p in folder.iterdir() if p.is_file() and p.name != "README.md"):
        groups.setdefault(stem(path.name), []).append(path)
    return sorted(groups.items())


def row(name: str, files: list[Path]) -> str:
    data: dict = {}
    json_file = next((f for f in files if f.suffix == ".json"), None)
    if json_file is not None:
        loaded = json.loads(json_file.read_text())
        data = loaded if isinstance(loaded, dict) else {}
    links = " ".join(f"[{_kind(f)}]({f.relative_to(RESULTS).as_posix()})" for f in files)
    cells = [
        _what(files, data),
        _device(name, data),
        _commit(name, files, data),
        _date(name, data),
        f"`{_command(files, data)}`",
        links,
    ]
    return "| " + " | ".join(_cell(c) for c in cells) + " |"


def _kind(path: Path) -> str:
    """A short link label: the extension, or what a profile beside a JSON holds."""
    rest = path.name[len(stem(path.name)) :]
    label = rest.lstrip("-.") or path.suffix.lstrip(".")
    return label.removesuffix(".txt") if label.endswith(".txt") and label != "txt" else label


def index() -> str:
    lines = [
        "# Result files",
        "",
        "Generated by `tools/results_index.py` from the files in these folders; do not edit by hand",
        "(`python tools/results_index.py` rewrites it, `tests/test_docs.py` checks it is current).",
        "Each row is one run; its files share a name. Where the files do not record the command,",
        "`≈` marks one rebuilt from the settings they do record. Commands are quoted as they ran:",
        "`benchmarks/{contact,engine,grasp_step}_compare.py` and `benchmarks/determinism.py` now live in",
        "`tools/`, `benchmarks/train_mt_ppo.py` in `examples/`. Reports written at the time may name",
        "files since removed (failed, killed or superseded runs; docs/performance.md says what the",
        "failures taught). The documents that explain these figures are [README.md](../../README.md),",
        "[docs/performance.md](../../docs/performance.md), [docs/fidelity.md](../../docs/fidelity.md)",
        "and [docs/training.md](../../docs/training.md).",
        "",
    ]
    folders = [RESULTS / kind for kind in KINDS if (RESULTS / kind).is_dir()]
    folders += sorted(p for p in RESULTS.iterdir() if p.is_dir() and p.name not in KINDS)
    stray = [p for p in RESULTS.iterdir() if p.is_file() and p.name != "README.md"]
    if stray:
        folders.insert(0, RESULTS)
    for folder in folders:
        title = "(not yet filed: `python tools/results_index.py --sort`)" if folder == RESULTS else ""
        about = KINDS.get(folder.name, ((), ""))[1]
        heading = f"## {folder.relative_to(RESULTS).as_posix()}/" if folder != RESULTS else "## top level"
        lines += [heading + (f" {title}" if title else ""), ""]
        if about:
            lines += [about[0].upper() + about[1:] + ".", ""]
        lines += [
            "| what | device | commit | date | command | files |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        lines += [row(name, files) for name, files in runs(folder)]
        lines.append("")
    return "\n".join(lines)


def sort_stray() -> None:
    for path in sorted(p for p in RESULTS.iterdir() if p.is_file() and p.name != "README.md"):
        kind = next((k for k, (prefixes, _) in KINDS.items() if path.name.startswith(prefixes)), None)
        if kind is None:
            print(f"left at the top level (no kind matches its name): {path.name}")
            continue
        (RESULTS / kind).mkdir(exist_ok=True)
        subprocess.run(["git", "mv", path.name, f"{kind}/{path.name}"], cwd=RESULTS, check=True)
        print(f"{path.name} -> {kind}/")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the index is out of date")
    parser.add_argument("--sort", action="store_true", help="file top-level result files by kind first")
    args = parser.parse_args()
    if args.sort:
        sort_stray()
    text = index()
    if args.check:
        if not INDEX.exists() or INDEX.read_text() != text:
            sys.exit(f"{INDEX.relative_to(ROOT)} is out of date: run python tools/results_index.py")
        return
    INDEX.write_text(text)
    print(f"-> {INDEX.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
