"""Pre-flight check of the SLURM route (run by `bash claychain cluster`).

Fails in one line, before Snakemake submits anything, where the cluster would otherwise
leave the run waiting: no SLURM commands, no account or partition set, an account the
user is not associated with, a partition that does not exist or is down, a memory
request larger than every node of the partition. On success prints the Snakemake
arguments that fit the requests to the partition's largest node (one per line):
``--max-threads`` = its CPUs, ``--group-components scale=K`` with K members of the scale
group per job (K x 1 CPU and K x their mem_mb within the node).
"""

import getpass
import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

PROFILE = Path(__file__).with_name("config.yaml")


def fail(message):
    sys.exit(f"claychain cluster: {message}")


def run(*command):
    done = subprocess.run(command, capture_output=True, text=True)
    return done.returncode, done.stdout.strip(), done.stderr.strip()


def check_account(account):
    """The user must be associated with the account (sacctmgr), where accounting answers."""
    user = getpass.getuser()
    code, out, err = run(
        "sacctmgr", "-n", "-P", "show", "associations", f"user={user}", "format=account"
    )
    if code != 0 or not out:
        print(
            f"claychain cluster: warning: sacctmgr lists no association for {user} "
            f"({err or 'no accounting?'}); account '{account}' not checked",
            file=sys.stderr,
        )
        return
    accounts = sorted({line.strip() for line in out.splitlines() if line.strip()})
    if account.lower() not in {a.lower() for a in accounts}:
        fail(
            f"account '{account}' (SLURM_ACCOUNT) is not one of {user}'s accounts: "
            f"{', '.join(accounts)}"
        )


def partition_nodes(partition):
    """(CPUs, memory in MB) of each node of the partition; fails if there is none."""
    code, out, err = run("sinfo", "-h", "-p", partition, "-N", "-o", "%c %m %a")
    if code != 0:
        fail(f"sinfo failed: {err}")
    if not out:
        _, known, _ = run("sinfo", "-h", "-o", "%R")
        fail(
            f"partition '{partition}' (SLURM_PARTITION) does not exist; partitions: "
            f"{', '.join(sorted(set(known.split())))}"
        )
    nodes = []
    for line in out.splitlines():
        cpus, memory, availability = line.split()
        if availability != "up":
            continue
        nodes.append((int(cpus), int(memory.rstrip("+"))))
    if not nodes:
        fail(f"partition '{partition}' is not up (sinfo -p {partition})")
    return nodes


def main():
    for tool in ("sbatch", "sinfo", "sacct", "sacctmgr"):
        if shutil.which(tool) is None:
            fail(f"'{tool}' not found: run this on a SLURM login node")
    account = os.environ.get("SLURM_ACCOUNT", "").strip()
    partition = os.environ.get("SLURM_PARTITION", "").strip()
    if not account or not partition:
        fail(
            "set SLURM_ACCOUNT and SLURM_PARTITION (environment, or cluster.env at the "
            "repository's root: SLURM_ACCOUNT=... and SLURM_PARTITION=...)"
        )
    check_account(account)
    nodes = partition_nodes(partition)
    cpus = max(c for c, _ in nodes)
    memory = max(m for _, m in nodes)
    profile = yaml.safe_load(PROFILE.read_text())
    requests = {
        rule: int(values.get("mem_mb", profile["default-resources"]["mem_mb"]))
        for rule, values in profile["set-resources"].items()
    }
    too_big = {rule: mb for rule, mb in requests.items() if mb > memory}
    if too_big:
        fail(
            f"the largest node of '{partition}' has {memory} MB; these rules ask more "
            f"(workflow/profiles/slurm/config.yaml): {too_big}"
        )
    member = requests.get("micro_scale_realization", 2000)
    group = max(1, min(cpus, memory // member))
    print(
        f"claychain cluster: account {account}, partition {partition}, largest node "
        f"{cpus} CPUs / {memory} MB: threads capped at {cpus}, scale group of {group}",
        file=sys.stderr,
    )
    print("--max-threads", cpus, "--group-components", f"scale={group}", sep="\n")


if __name__ == "__main__":
    main()
