#!/usr/bin/env bash
# Stop the daemons tests/slurm/start_cluster.sh started in DIR (slurmd, slurmctld, munged), by the pids in
# DIR/run/*.pid only: other daemons of the same name on the machine are left alone. Safe to call twice or
# after a start that failed half-way.
set -uo pipefail

DIR=${1:?usage: stop_cluster.sh DIR}

stop() {  # stop NAME: TERM the pid in DIR/run/NAME.pid, wait up to 10 s, then KILL
    local pidfile="$DIR/run/$1.pid" pid
    [ -s "$pidfile" ] || return 0
    pid=$(cat "$pidfile")
    if kill -0 "$pid" 2>/dev/null; then
        kill -TERM "$pid" 2>/dev/null
        for _ in $(seq 40); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.25
        done
        kill -0 "$pid" 2>/dev/null && kill -KILL "$pid" 2>/dev/null
    fi
    rm -f "$pidfile"
}

# jobs still running would outlive slurmd under proctrack/linuxproc
if [ -f "$DIR/slurm.conf" ] && [ -s "$DIR/run/slurmctld.pid" ]; then
    SLURM_CONF="$DIR/slurm.conf" scancel --quiet --user="$(id -un)" 2>/dev/null || true
fi
stop slurmd
stop slurmctld
stop munged
# the link start_cluster.sh made for srun inside jobs, when it points to DIR
if [ -L /run/slurm/conf ] && [ "$(readlink /run/slurm/conf)" = "$(cd "$DIR" 2>/dev/null && pwd)" ]; then
    rm -f /run/slurm/conf
    [ -e "$DIR/run/made-run-slurm" ] && rmdir /run/slurm 2>/dev/null
fi
exit 0
