"""The SLURM route without a cluster (docs/howto-cluster.md): the profile covers every
remote rule, the pre-flight check refuses what would leave a run waiting and fits the
requests to the node, the sacct shim reports cancelled jobs as CANCELLED. Fake SLURM
commands on PATH stand in for the cluster (benchmarks/cluster/check_slurm.py runs the
real one)."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
PROFILE = REPO / "workflow/profiles/slurm"


def remote_rules():
    rules = set()
    for path in (REPO / "workflow/rules").glob("*.smk"):
        for block in re.split(r"\n(?=rule )", path.read_text()):
            match = re.match(r"rule (\w+):", block)
            if match and "localrule: True" not in block:
                rules.add(match.group(1))
    return rules


def test_profile_covers_every_remote_rule():
    profile = yaml.safe_load((PROFILE / "config.yaml").read_text())
    assert profile["executor"] == "slurm"
    assert profile["retries"] >= 1
    assert profile["default-resources"]["slurm_account"] == "$SLURM_ACCOUNT"
    assert profile["default-resources"]["slurm_partition"] == "$SLURM_PARTITION"
    resources = profile["set-resources"]
    assert remote_rules() <= set(resources), remote_rules() - set(resources)
    assert "micro_scale" not in resources  # a local rule
    for rule, values in resources.items():
        assert {"mem_mb", "runtime"} <= set(values), rule
        assert "cpus_per_task" not in values  # threads drive --cpus-per-task


def fake_slurm(tmp_path, nodes="2 12000 up", accounts="claychain\nroot"):
    """sinfo/sacctmgr/sbatch/sacct that answer like a one-partition cluster."""
    bin_dir = tmp_path / "fake"
    bin_dir.mkdir()
    scripts = {
        "sinfo": f"""case "$*" in
*"-p claychain"*) printf '%s\\n' "{nodes}" ;;
*"-p "*) ;;
*) echo claychain ;;
esac""",
        "sacctmgr": f"printf '%s\\n' '{accounts}'",
        "sbatch": "exit 0",
        "sacct": "printf '12|CANCELLED by 0\\n13|RUNNING\\n14|PREEMPTED\\n15|COMPLETED\\n'",
    }
    for name, body in scripts.items():
        (bin_dir / name).write_text(f"#!/usr/bin/env bash\n{body}\n")
        (bin_dir / name).chmod(0o755)
    return bin_dir


def preflight(bin_dir, **env):
    environ = {k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}
    environ.update(env, PATH=f"{bin_dir}:{os.environ['PATH']}")
    return subprocess.run([sys.executable, str(PROFILE / "preflight.py")], env=environ,
                          capture_output=True, text=True)


@pytest.mark.parametrize("env, message", [
    ({}, "set SLURM_ACCOUNT and SLURM_PARTITION"),
    ({"SLURM_ACCOUNT": "your_account", "SLURM_PARTITION": "claychain"},
     "account 'your_account' (SLURM_ACCOUNT) is not one of"),
    ({"SLURM_ACCOUNT": "claychain", "SLURM_PARTITION": "your_partition"},
     "partition 'your_partition' (SLURM_PARTITION) does not exist; partitions: claychain"),
])
def test_preflight_refuses_what_would_hang(tmp_path, env, message):
    done = preflight(fake_slurm(tmp_path), **env)
    assert done.returncode == 1
    assert message in done.stderr


@pytest.mark.parametrize("nodes, threads, group", [
    ("2 12000 up", 2, 2),
    ("32 64000 up", 32, 32),
    ("8 8000 up", 8, 4),  # memory bounds the scale group: 4 x 2000 MB
])
def test_preflight_fits_threads_and_group_to_the_node(tmp_path, nodes, threads, group):
    done = preflight(fake_slurm(tmp_path, nodes=nodes), SLURM_ACCOUNT="claychain",
                     SLURM_PARTITION="claychain")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["--max-threads", str(threads), "--group-components",
                                   f"scale={group}"]


def test_preflight_refuses_a_node_too_small(tmp_path):
    done = preflight(fake_slurm(tmp_path, nodes="1 3000 up"), SLURM_ACCOUNT="claychain",
                     SLURM_PARTITION="claychain")
    assert done.returncode == 1
    assert "largest node of 'claychain' has 3000 MB" in done.stderr


def test_sacct_shim_reports_cancelled_and_preempted_as_cancelled(tmp_path):
    bin_dir = fake_slurm(tmp_path)
    env = dict(os.environ, PATH=f"{PROFILE / 'bin'}:{bin_dir}:{os.environ['PATH']}")
    out = subprocess.run(["sacct", "-X", "--parsable2"], env=env, capture_output=True,
                         text=True, check=True).stdout
    assert out.split() == ["12|CANCELLED", "13|RUNNING", "14|CANCELLED", "15|COMPLETED"]
