#!/usr/bin/env bash
# local-slurm.sh start DIR [KEY=VALUE...] | stop DIR: a one-node Slurm
# cluster on this machine for the tests (Debian slurm-wlm + munge, run as
# root), all state in DIR. KEY=VALUE lines go into slurm.conf as given,
# over the defaults below (e.g. MaxJobCount=60 MaxArraySize=20: a cluster
# with a site's limits). `start` writes DIR/slurm.conf, starts munged, slurmctld and slurmd,
# waits until the node is idle and prints `export SLURM_CONF=...` for the
# caller to eval. `stop` kills the three daemons by the process ids recorded
# in DIR (never by name: other clusters may run here) and waits for them.
set -u
cmd=${1:-}; dir=${2:-}
[ -n "$cmd" ] && [ -n "$dir" ] || { echo "usage: $0 start|stop DIR [KEY=VALUE...]" >&2; exit 2; }
shift 2
for kv in "$@"; do
	case "$kv" in
	[A-Za-z]*=*) ;;
	*) echo "local-slurm: '$kv' is not a slurm.conf KEY=VALUE" >&2; exit 2 ;;
	esac
done

stop() {
	local f pid
	for f in slurmd slurmctld munged; do
		[ -s "$dir/$f.pid" ] || continue
		pid=$(cat "$dir/$f.pid")
		kill "$pid" 2>/dev/null
		for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
		kill -9 "$pid" 2>/dev/null
		rm -f "$dir/$f.pid"
	done
}

if [ "$cmd" = stop ]; then stop; exit 0; fi
[ "$cmd" = start ] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }
for p in munged slurmctld slurmd sbatch; do
	command -v $p >/dev/null || { echo "local-slurm: '$p' not found (make deps installs slurm-wlm and munge)" >&2; exit 1; }
done
[ "$(id -u)" = 0 ] || { echo "local-slurm: needs root (slurmd runs jobs as their user)" >&2; exit 1; }

dir=$(mkdir -p "$dir" && cd "$dir" && pwd)
mkdir -p "$dir/state" "$dir/spool" "$dir/log"
cpus=$(nproc)
mem_mb=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024 ))
host=$(hostname -s)
dd if=/dev/urandom of="$dir/munge.key" bs=1024 count=1 2>/dev/null
chmod 400 "$dir/munge.key"
cat > "$dir/slurm.conf" <<CONF
ClusterName=voxdagtest
SlurmctldHost=$host
AuthType=auth/munge
AuthInfo=socket=$dir/munge.socket
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$((20000 + RANDOM % 10000))
SlurmdPort=$((30000 + RANDOM % 10000))
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
SchedulerType=sched/builtin
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
MpiDefault=none
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=30
MinJobAge=600
JobAcctGatherType=jobacct_gather/none
NodeName=$host CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
for kv in "$@"; do # the caller's, in place of a default
	sed -i "/^${kv%%=*}=/d" "$dir/slurm.conf"
	sed -i "1i $kv" "$dir/slurm.conf"
done
trap 'stop' ERR
munged --force --socket="$dir/munge.socket" --key-file="$dir/munge.key" \
	--pid-file="$dir/munged.pid" --log-file="$dir/log/munged.log" \
	--seed-file="$dir/munge.seed" || { echo "local-slurm: munged did not start" >&2; exit 1; }
export SLURM_CONF=$dir/slurm.conf
slurmctld -f "$dir/slurm.conf" -i || { echo "local-slurm: slurmctld did not start (see $dir/log)" >&2; stop; exit 1; }
slurmd -f "$dir/slurm.conf" || { echo "local-slurm: slurmd did not start (see $dir/log)" >&2; stop; exit 1; }
for _ in $(seq 100); do
	state=$(sinfo -h -o %T 2>/dev/null | head -n 1)
	[ "$state" = idle ] && { echo "export SLURM_CONF=$dir/slurm.conf"; exit 0; }
	sleep 0.2
done
echo "local-slurm: the node did not become idle (state '$state'; see $dir/log)" >&2
stop
exit 1
