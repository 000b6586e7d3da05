#!/usr/bin/env bash
# Start a one-node SLURM cluster on localhost inside DIR (munged, slurmctld, slurmd), for tests/test_slurm.py.
#
#   tests/slurm/start_cluster.sh DIR      # writes DIR/slurm.conf, DIR/env; prints nothing on success
#   source DIR/env                        # SLURM_CONF for sbatch, squeue, sacct, scontrol
#   tests/slurm/stop_cluster.sh DIR       # stops exactly the daemons this script started
#
# Everything lives under DIR but for the link /run/slurm/conf -> DIR (see below; stop_cluster.sh removes it):
# its own munge key and socket (a munged already running on the machine is left alone), its own ports, state,
# spool, logs and pid files. No cgroups (proctrack/linuxproc, task/none) and no accounting database
# (accounting_storage/none: sacct and sacctmgr have nothing to report; squeue shows finished jobs for
# MinJobAge seconds). Needs root or a user that may run the daemons (Debian: apt-get install slurm-wlm munge).
# Exit status: 0 when the node is IDLE, 2 when a command is missing, 1 when a daemon does not come up (its log
# is printed) or another cluster's configuration is in the way.
set -euo pipefail

DIR=${1:?usage: start_cluster.sh DIR}
mkdir -p "$DIR"
DIR=$(cd "$DIR" && pwd)

for cmd in munged slurmctld slurmd sbatch squeue sacct scontrol sinfo; do
    if ! command -v "$cmd" >/dev/null 2>&1 && [ ! -x "/usr/sbin/$cmd" ]; then
        echo "start_cluster.sh: '$cmd' not found (Debian: apt-get install slurm-wlm munge)" >&2
        exit 2
    fi
done
PATH="$PATH:/usr/sbin"

mkdir -p "$DIR"/{munge,state,spool,log,run}
chmod 0700 "$DIR/munge"

# two free TCP ports on localhost, for slurmctld and slurmd
read -r CTLD_PORT SLURMD_PORT < <(python3 - <<'EOF'
import socket
socks = [socket.socket() for _ in range(2)]
for s in socks:
    s.bind(("127.0.0.1", 0))
print(*(s.getsockname()[1] for s in socks))
EOF
)

CPUS=$(nproc)
# RealMemory below the free memory (MB), leaving a quarter for everything else; slurmd drains a node whose
# RealMemory exceeds what it finds
FREE_MB=$(awk '/MemAvailable/ {print int($2 / 1024)}' /proc/meminfo)
MEM_MB=$((FREE_MB * 3 / 4))
USER_NAME=$(id -un)

# munge: a fresh key and a private socket
dd if=/dev/urandom of="$DIR/munge/munge.key" bs=1024 count=1 status=none
chmod 0400 "$DIR/munge/munge.key"
SOCKET="$DIR/munge/munge.socket"
munged --force \
    --key-file="$DIR/munge/munge.key" \
    --socket="$SOCKET" \
    --pid-file="$DIR/run/munged.pid" \
    --log-file="$DIR/log/munged.log" \
    --seed-file="$DIR/munge/munged.seed"

cat >"$DIR/slurm.conf" <<EOF
# one-node test cluster written by tests/slurm/start_cluster.sh
ClusterName=imupipetest
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=$USER_NAME
SlurmdUser=$USER_NAME
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$SOCKET
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/run/slurmctld.pid
SlurmdPidFile=$DIR/run/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
# finished jobs stay visible to squeue/sacct (no database) for an hour
MinJobAge=3600
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$MEM_MB State=UNKNOWN
PartitionName=test Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
# Inside a job the executor's job step drops every SLURM_* variable (SLURM_CONF too) before its `srun`, which
# then looks for /etc/slurm/slurm.conf and next for /run/slurm/conf/slurm.conf (where a configless slurmd
# keeps its copy). A machine with its own /etc/slurm/slurm.conf would send those steps to its own cluster.
if [ -e /etc/slurm/slurm.conf ]; then
    echo "start_cluster.sh: /etc/slurm/slurm.conf exists: job steps would use that cluster" >&2
    exit 1
fi
if [ -e /run/slurm/conf ] || [ -L /run/slurm/conf ]; then
    echo "start_cluster.sh: /run/slurm/conf exists (another slurmd's configuration): not replacing it" >&2
    exit 1
fi
[ -d /run/slurm ] || { mkdir -p /run/slurm && touch "$DIR/run/made-run-slurm"; }
ln -s "$DIR" /run/slurm/conf
printf 'export SLURM_CONF=%q\n' "$DIR/slurm.conf" >"$DIR/env"
export SLURM_CONF="$DIR/slurm.conf"

show_logs() {
    for f in "$DIR"/log/*.log; do
        echo "---- $f" >&2
        tail -n 30 "$f" >&2 || true
    done
}

# -c: clear any saved state (the directory is new anyway); -i: ignore state errors
if ! slurmctld -c -i; then
    echo "start_cluster.sh: slurmctld did not start" >&2
    show_logs
    exit 1
fi
if ! slurmd -N localhost; then
    echo "start_cluster.sh: slurmd did not start" >&2
    show_logs
    exit 1
fi

# wait for the node to register and become IDLE (up to 30 s)
for _ in $(seq 60); do
    state=$(sinfo -h -n localhost -o %T 2>/dev/null || true)
    case "$state" in
        idle* | mixed* | allocated*) exit 0 ;;
    esac
    sleep 0.5
done
echo "start_cluster.sh: node localhost did not become idle (state: '${state:-none}')" >&2
show_logs
exit 1
