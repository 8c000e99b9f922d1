#!/usr/bin/env bash
# A single-node SLURM on localhost for the cluster check (root only, Debian 12):
# munge + mariadb + slurmdbd (so that sacct answers, as on a real cluster) + slurmctld +
# slurmd, no cgroups. Idempotent: daemons already up are left as they are.
#   bash benchmarks/cluster/start_slurm.sh          install if missing, configure, start
#   bash benchmarks/cluster/start_slurm.sh stop     stop the daemons it started
# The node: this machine's CPUs (or $SLURM_NODE_CPUS), $SLURM_NODE_MEM_MB of memory
# (default 12000), partition "claychain", account "claychain" for the current user.
# Daemon logs: /var/log/slurm/{slurmctld,slurmd,slurmdbd}.log
set -euo pipefail

CLUSTER=claychain
PARTITION=${SLURM_TEST_PARTITION:-claychain}
ACCOUNT=${SLURM_TEST_ACCOUNT:-claychain}
NODE=$(hostname -s)
CPUS=${SLURM_NODE_CPUS:-$(nproc)}
MEM=${SLURM_NODE_MEM_MB:-12000}
RUN=/run/claychain-slurm

if [ "${1:-}" = stop ]; then
    for daemon in slurmd slurmctld slurmdbd; do
        [ -f "$RUN/$daemon.pid" ] && kill "$(cat "$RUN/$daemon.pid")" 2>/dev/null || true
    done
    [ -f /run/mysqld/claychain.pid ] && kill "$(cat /run/mysqld/claychain.pid)" 2>/dev/null || true
    [ -f "$RUN/munged.pid" ] && kill "$(cat "$RUN/munged.pid")" 2>/dev/null || true
    exit 0
fi

[ "$(id -u)" -eq 0 ] || { echo "start_slurm.sh: run as root" >&2; exit 2; }
if ! command -v slurmctld >/dev/null || ! command -v slurmdbd >/dev/null \
    || ! command -v mariadbd >/dev/null || ! command -v munged >/dev/null; then
    apt-get -o DPkg::Lock::Timeout=600 update -qq
    DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -qq \
        slurm-wlm munge slurmdbd mariadb-server >/dev/null
fi
mkdir -p "$RUN" /var/log/slurm /var/spool/slurmctld /var/spool/slurmd /run/munge /run/mysqld
chown slurm:slurm "$RUN" /var/log/slurm /var/spool/slurmctld
chown munge:munge /run/munge
chown mysql:mysql /run/mysqld

# munge: the key the package made
if ! pgrep -x munged >/dev/null; then
    [ -s /etc/munge/munge.key ] || { mungekey --create 2>/dev/null || create-munge-key; }
    chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
    runuser -u munge -- munged --pid-file /run/munge/munged.pid
    cp /run/munge/munged.pid "$RUN/munged.pid" 2>/dev/null || true
fi

# mariadb for slurmdbd
if ! pgrep -x mariadbd >/dev/null && ! pgrep -x mysqld >/dev/null; then
    [ -d /var/lib/mysql/mysql ] || mariadb-install-db --user=mysql >/dev/null
    mariadbd --user=mysql --pid-file=/run/mysqld/claychain.pid --skip-networking=0 \
        --bind-address=127.0.0.1 >/var/log/slurm/mariadb.log 2>&1 &
    for _ in $(seq 60); do mariadb -e 'select 1' >/dev/null 2>&1 && break; sleep 1; done
fi
mariadb -e "CREATE DATABASE IF NOT EXISTS slurm_acct_db;
CREATE USER IF NOT EXISTS 'slurm'@'localhost' IDENTIFIED BY 'slurmdbpass';
GRANT ALL ON slurm_acct_db.* TO 'slurm'@'localhost'; FLUSH PRIVILEGES;"

cat > /etc/slurm/slurmdbd.conf <<EOF
AuthType=auth/munge
DbdHost=localhost
DbdPort=6819
SlurmUser=slurm
LogFile=/var/log/slurm/slurmdbd.log
PidFile=$RUN/slurmdbd.pid
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=slurm
StoragePass=slurmdbpass
StorageLoc=slurm_acct_db
EOF
chown slurm:slurm /etc/slurm/slurmdbd.conf && chmod 600 /etc/slurm/slurmdbd.conf

cat > /etc/slurm/slurm.conf <<EOF
ClusterName=$CLUSTER
SlurmctldHost=$NODE(127.0.0.1)
AuthType=auth/munge
SlurmUser=slurm
SlurmctldPidFile=$RUN/slurmctld.pid
SlurmdPidFile=$RUN/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/linux
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
AccountingStorageEnforce=associations,limits
AccountingStoreFlags=job_comment
ReturnToService=2
MinJobAge=300
KillWait=10
NodeName=$NODE NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$MEM State=UNKNOWN
PartitionName=$PARTITION Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF

if ! pgrep -x slurmdbd >/dev/null; then
    slurmdbd
    for _ in $(seq 60); do sacctmgr -n list cluster >/dev/null 2>&1 && break; sleep 1; done
fi
sacctmgr -i add cluster "$CLUSTER" >/dev/null 2>&1 || true
sacctmgr -i add account "$ACCOUNT" Cluster="$CLUSTER" >/dev/null 2>&1 || true
sacctmgr -i add user "$(id -un)" Account="$ACCOUNT" Cluster="$CLUSTER" >/dev/null 2>&1 || true
pgrep -x slurmctld >/dev/null || slurmctld
pgrep -x slurmd >/dev/null || slurmd
for _ in $(seq 60); do
    sinfo -h -N -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)' && break
    sleep 1
done
scontrol update NodeName="$NODE" State=RESUME >/dev/null 2>&1 || true
sinfo -N -o '%N %P %c %m %T'
echo "account: $ACCOUNT  partition: $PARTITION"
