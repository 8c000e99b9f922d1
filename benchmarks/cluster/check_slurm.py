"""Integration check of the SLURM route on a single-node SLURM on this machine.

    python benchmarks/cluster/check_slurm.py [--full] [--workdir DIR] [--no-start]
                                             [--skip-local] [--compare-only]

Starts the SLURM daemons (start_slurm.sh, as root), lays the committed tree twice under
DIR (local/ and cluster/; a reduced configuration unless --full), runs ``bash claychain
cluster`` in cluster/ and scancels the first micro case's job once it has written its
checkpoint (Snakemake must resubmit it and the new job resume), runs ``snakemake
--cores 2`` in local/, and compares every netCDF of the two runs with xarray (wall
times left out). Prints the cancelled job and its successor and one line per netCDF;
exits non-zero if anything differs or the cancelled case was not resumed. The steps and
logs in full: docs/performance.md, "benchmarks.cluster.check_slurm".
"""

import argparse
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import xarray as xr
import yaml

REPO = Path(__file__).resolve().parents[2]


def reduce_config(path):
    config = yaml.safe_load(path.read_text())
    micro = config["micro"]
    micro["n_points"] = 300
    micro["vtk_snapshots"] = False
    micro["cases"] = {
        name: entry for name, entry in micro["cases"].items()
        if name in ("heterogeneous", "confined")
    }
    micro["studies"]["scale"].update(fractions=[0.25], realizations=2)
    for packing in config["packings"].values():
        packing["n_particles"] = 60
    path.write_text(yaml.safe_dump(config, sort_keys=False))


def lay_tree(target, full):
    target.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(REPO), "archive", "HEAD"], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(target)], input=archive, check=True)
    if not full:
        reduce_config(target / "config" / "config.yaml")


def sacct_rows():
    out = subprocess.run(
        ["sacct", "-X", "-n", "-P", "--starttime", "now-1days",
         "--format=JobIdRaw,State,Comment%80,Elapsed"],
        capture_output=True, text=True).stdout
    return [line.split("|") for line in out.splitlines() if line]


def cancel_first_checkpointed_case(tree, report, stop):
    """scancel the micro case whose checkpoint appears first."""
    while not stop.is_set():
        for checkpoint in sorted((tree / "results" / "micro").glob("*.checkpoint.npz")):
            case = checkpoint.name.removesuffix(".checkpoint.npz")
            queue = subprocess.run(["squeue", "-h", "-o", "%i|%k|%T"], capture_output=True,
                                   text=True).stdout
            for line in queue.splitlines():
                job, comment, state = line.split("|")
                if comment.startswith("rule_micro_case") and comment.endswith(case) \
                        and state == "RUNNING":
                    time.sleep(2)
                    subprocess.run(["scancel", job], check=True)
                    report.update(case=case, job=job, at=time.time())
                    print(f"check: scancel {job} (micro_case {case}, checkpoint present)",
                          flush=True)
                    return
        time.sleep(1)


def wall_time(variable):
    """A measured wall time (e.g. the packing's settle_time), which no two runs share."""
    return "wall time" in str(variable.attrs.get("long_name", "")).lower()


def compare(local, cluster):
    """Each netCDF's data variables equal (xarray), measured wall times left out."""
    failures = 0
    for path in sorted((local / "results").rglob("*.nc")):
        other = cluster / path.relative_to(local)
        name = path.relative_to(local)
        if not other.exists():
            print(f"  MISSING {name}")
            failures += 1
            continue
        with xr.open_dataset(path) as a, xr.open_dataset(other) as b:
            skipped = [v for v in a.data_vars if wall_time(a[v])]
            differ = [v for v in a.data_vars if v not in skipped
                      and (v not in b.data_vars or not a[v].equals(b[v]))]
            extra = [v for v in b.data_vars if v not in a.data_vars]
        status = "equal" if not differ and not extra else f"DIFFER {differ + extra}"
        failures += bool(differ or extra)
        note = f", wall times not compared: {skipped}" if skipped else ""
        print(f"  {status:6s} {name} ({len(a.data_vars)} data variables{note})")
    return failures


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--full", action="store_true", help="the default chain, not reduced")
    parser.add_argument("--workdir", type=Path, default=Path("/tmp/claychain-cluster-check"))
    parser.add_argument("--no-start", action="store_true", help="SLURM is already up")
    parser.add_argument("--skip-local", action="store_true",
                        help="reuse DIR/local from an earlier check")
    parser.add_argument("--compare-only", action="store_true",
                        help="only compare the netCDFs of DIR/local and DIR/cluster")
    args = parser.parse_args()
    work = args.workdir
    if args.compare_only:
        print("check: netCDF data variables, local vs cluster:")
        sys.exit(1 if compare(work / "local", work / "cluster") else 0)
    if not args.no_start:
        subprocess.run(["bash", str(REPO / "benchmarks/cluster/start_slurm.sh")], check=True)
    for name in ("cluster",) + (() if args.skip_local else ("local",)):
        subprocess.run(["rm", "-rf", str(work / name)], check=True)
        lay_tree(work / name, args.full)
    env = dict(os.environ, SLURM_ACCOUNT=os.environ.get("SLURM_TEST_ACCOUNT", "claychain"),
               SLURM_PARTITION=os.environ.get("SLURM_TEST_PARTITION", "claychain"))
    venv = os.environ.get("CLAYCHAIN_VENV", str(REPO / ".venv"))
    env["CLAYCHAIN_VENV"] = venv

    report, stop = {}, threading.Event()
    watcher = threading.Thread(target=cancel_first_checkpointed_case,
                               args=(work / "cluster", report, stop), daemon=True)
    watcher.start()
    start = time.time()
    with open(work / "cluster.log", "w") as log:
        cluster = subprocess.run(["bash", "claychain", "cluster"], cwd=work / "cluster",
                                 env=env, stdout=log, stderr=subprocess.STDOUT)
    stop.set()
    cluster_s = time.time() - start
    print(f"check: cluster run {cluster_s:.0f} s, exit {cluster.returncode} "
          f"(log {work / 'cluster.log'})", flush=True)

    local_s = None
    if not args.skip_local:
        start = time.time()
        with open(work / "local.log", "w") as log:
            local = subprocess.run([f"{venv}/bin/snakemake", "--cores", "2"],
                                   cwd=work / "local", stdout=log, stderr=subprocess.STDOUT)
        local_s = time.time() - start
        print(f"check: local run {local_s:.0f} s, exit {local.returncode}", flush=True)

    failures = int(cluster.returncode != 0)
    if report:
        case = report["case"]
        jobs = [row for row in sacct_rows() if row[2].endswith(f"micro_case_{case}")
                or row[2].endswith(f"micro_case/{case}") or row[2].endswith(case)]
        print(f"check: sacct for micro_case {case}:")
        for row in jobs:
            print("   ", " ".join(row))
        case_log = (work / "cluster/results/logs/micro_case" / f"{case}.log")
        resumed = case_log.exists() and "resuming after checkpoint" in case_log.read_text()
        retried = any(row[1] == "COMPLETED" and row[0] != report["job"] for row in jobs)
        print(f"check: resubmitted and completed: {retried}; resumed from its checkpoint: "
              f"{resumed} ({case_log})")
        failures += (not retried) + (not resumed)
    else:
        print("check: no micro case was cancelled (none seen running with a checkpoint)")
        failures += 1
    print("check: netCDF data variables, local vs cluster:")
    failures += compare(work / "local", work / "cluster")
    print(f"check: {'PASSED' if not failures else f'FAILED ({failures})'}")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
