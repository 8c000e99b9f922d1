"""The launcher script (claychain): its help, its refusal of an unknown command, and how
``run`` hands targets, options, configuration files and --set values to Snakemake, refuses
a bad configuration file in one line and a second run in the same folder."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _claychain(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(ROOT / "claychain"), *args], capture_output=True,
                          text=True, timeout=60)


@pytest.mark.parametrize("flag", ["--help", "-h", "help"])
def test_the_launcher_help_lists_commands_presets_and_examples(flag):
    result = _claychain(flag)
    assert result.returncode == 0, result.stderr
    for word in ("run", "test", "setup", "--set", "Examples:"):
        assert word in result.stdout
    blocks = result.stdout.split("Presets")[1].split("Examples:")[0].split("\n  config/paper/")
    described = {block.split("\n", 1)[0].strip(): " ".join(block.split("\n", 1)[1].split())
                 for block in blocks[1:]}
    for preset in sorted((ROOT / "config/paper").glob("*.yaml")):
        first = next(line for line in preset.read_text().splitlines() if line.startswith("#"))
        text = described[preset.name]
        # the description starts as the file's comment does and ends with its sentence
        assert text.startswith(" ".join(first.lstrip("# ").split()[:6])), (preset.name, text)
        assert text.endswith((".", ")")) and "Use:" not in text, (preset.name, text)


def test_an_unknown_command_prints_the_usage_on_stderr_and_exits_2():
    result = _claychain("bogus")
    assert result.returncode == 2
    assert result.stdout == ""
    assert "unknown command 'bogus'" in result.stderr and "usage:" in result.stderr


# ------------------------------------------------ run: arguments, config files, the lock

A, B = "config/paper/macro_r473.yaml", "config/paper/macro_r599.yaml"
OVERLAY = ".snakemake/claychain/overrides.yaml"


@pytest.fixture
def launcher(tmp_path: Path) -> Path:
    """The launcher in a folder of its own, whose 'venv' holds this Python and a stand-in
    snakemake that writes its arguments to $ARGS, one a line, and becomes ``sleep $HOLD``
    (the process that holds the run lock: killing it releases the lock)."""
    for name in ("config", "shared", "workflow"):
        (tmp_path / name).symlink_to(ROOT / name)
    for name in ("claychain", "pyproject.toml"):
        shutil.copy(ROOT / name, tmp_path / name)
    bin_dir = tmp_path / "venv" / "bin"
    bin_dir.mkdir(parents=True)
    (bin_dir / "python").write_text(f'#!/bin/sh\nexec {sys.executable} "$@"\n')
    (bin_dir / "snakemake").write_text('#!/bin/sh\nprintf "%s\\n" "$@" > "$ARGS"\nexec sleep "${HOLD:-0}"\n')
    for script in bin_dir.iterdir():
        script.chmod(0o755)
    digest = hashlib.sha256((tmp_path / "pyproject.toml").read_bytes()).hexdigest()
    (tmp_path / "venv" / ".claychain-installed").write_text(digest + "\n")
    return tmp_path


def _run(launcher: Path, *args: str, hold: float = 0.0) -> tuple[subprocess.CompletedProcess, list[str] | None]:
    """``bash claychain run ARGS``: the result and the arguments snakemake got (None: not run)."""
    received = launcher / "snakemake-args.txt"
    received.unlink(missing_ok=True)
    env = {**os.environ, "CLAYCHAIN_VENV": str(launcher / "venv"), "ARGS": str(received), "HOLD": str(hold)}
    result = subprocess.run(["bash", str(launcher / "claychain"), "run", *args], capture_output=True,
                            text=True, timeout=60, env=env)
    return result, received.read_text().splitlines() if received.exists() else None


@pytest.mark.parametrize("args, expected", [
    (["--configfile", A, "results/x.nc", "-n"], ["results/x.nc", "-n", "--configfile", A]),
    (["results/x.nc", "--configfile", A, "-n"], ["results/x.nc", "-n", "--configfile", A]),
    (["-n", "--configfile", A, B, "results/x.nc"], ["-n", "results/x.nc", "--configfile", A, B]),
    (["--configfile=" + A, "--configfile", B, "--forcerun", "macro_case"],
     ["--forcerun", "macro_case", "--configfile", A, B]),
    (["--configfile=" + A, "--set", "macro.seed=3", "results/x.nc"],
     ["results/x.nc", "--configfile", A, OVERLAY]),
    # a dry run of --set lists the rules it reruns, not each job's block
    (["--set=macro.seed=3", "-n"], ["-n", "--quiet", "rules", "host", "--configfile", "config/config.yaml", OVERLAY]),
])
def test_targets_options_and_configfiles_reach_snakemake_as_meant(launcher, args, expected):
    """Targets are never read as configuration files, either form of --configfile counts,
    and the files go to Snakemake in the order given, a --set overlay at its place."""
    result, received = _run(launcher, *args)
    assert result.returncode == 0, result.stderr
    assert received == ["--cores", "2", *expected]
    if OVERLAY in expected:
        assert "seed: 3" in (launcher / OVERLAY).read_text()


def test_set_pairs_and_configfiles_merge_in_the_order_given(launcher):
    """Each run of --set pairs becomes an overlay at its place among the files: a pair
    before a file is overridden by it, one after it overrides it."""
    second = ".snakemake/claychain/overrides-2.yaml"
    result, received = _run(launcher, "--set", "macro.seed=3", "--configfile", A, "--set=macro.seed=5",
                            "--set", "micro.n_points=500", "--configfile", B)
    assert result.returncode == 0, result.stderr
    assert received == ["--cores", "2", "--configfile", "config/config.yaml", OVERLAY, A, second, B]
    assert "seed: 3" in (launcher / OVERLAY).read_text()
    later = (launcher / second).read_text()
    assert "seed: 5" in later and "n_points: 500" in later and "seed: 3" not in later


@pytest.mark.parametrize("content, words", [
    (None, "no such configuration file"),
    ("", "the configuration file is empty"),
    ("# only a comment\n", "the configuration file is empty"),
    ("- micro\n- macro\n", "must be a mapping of keys, not a YAML list"),
    ("micro:\n  n_points: [64\nmacro: {}\n", "not valid YAML: line 3, column 6"),
    ("micro:\n  n_points: 64\n  specimen_size_m: 0.004\n  n_points: 8000\n",
     "key 'n_points' is given twice, on lines 2 and 4"),
    ("micro:\n  specimen_size_m: .inf\n", "'micro.specimen_size_m': inf is not a finite number"),
    ("samples:\n  pellet:\n    voxel_size_m: .nan\n", "'samples.pellet.voxel_size_m': nan is not a finite number"),
])
def test_a_bad_configfile_is_one_line_naming_it(launcher, content, words):
    path = launcher / "mine.yaml"
    if content is not None:
        path.write_text(content)
    result, received = _run(launcher, "-n", "--configfile", "mine.yaml")
    assert result.returncode == 2 and received is None
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("claychain: ") and words in lines[0], result.stderr
    assert "mine.yaml" in lines[0] or "config key" in lines[0]


def test_a_second_run_in_the_same_folder_is_refused_naming_the_first_ones_pid(launcher):
    env = {**os.environ, "CLAYCHAIN_VENV": str(launcher / "venv"), "ARGS": str(launcher / "first.txt"),
           "HOLD": "30"}
    first = subprocess.Popen(["bash", str(launcher / "claychain"), "run"], env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while not (launcher / "first.txt").exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        result, received = _run(launcher)
        assert result.returncode == 1 and received is None
        assert f"another run (PID {first.pid}) holds this folder" in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
        # a dry run writes nothing: it may look while the first runs
        dry, received = _run(launcher, "-n")
        assert dry.returncode == 0 and received == ["--cores", "2", "-n"]
    finally:
        first.kill()
        first.communicate()
    # the lock goes with the process that held it
    again, received = _run(launcher)
    assert again.returncode == 0 and received == ["--cores", "2"]
