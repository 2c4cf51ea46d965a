#!/usr/bin/env bash
# A one-node Slurm cluster on localhost, for the tests that submit jobs (docs/architecture.md
# §Tests) and for trying vagsl's job scripts by hand.
#
#   scripts/slurm-local.sh start    start munged, slurmctld and slurmd (idempotent) and wait
#                                   until the node is idle
#   scripts/slurm-local.sh stop     cancel this cluster's jobs and stop its daemons
#   scripts/slurm-local.sh status   say whether it is up (exit 0) or not (exit 3)
#   scripts/slurm-local.sh env      print `export SLURM_CONF=…` for eval "$(… env)"
#
# Needs Debian's `slurm-wlm` and `munge` packages, and root (it re-runs itself under sudo).
# Daemons are started directly, not through systemd, so it works in containers and on CI.
#
# Everything lives in a private folder, $VAGSL_SLURM_DIR (default /tmp/vagsl-slurm): its own
# slurm.conf, munge key and munge socket, state, spool and logs (log/*.log). Nothing under
# /etc is read or written, and the daemons listen on their own ports (6917, 6918), so a real
# cluster on the same machine is left alone. Client commands find this cluster through
# SLURM_CONF=$VAGSL_SLURM_DIR/etc/slurm.conf (see `env`).
#
# Without cgroups (containers): proctrack/linuxproc tracks a job's processes, task/none binds
# nothing, and jobacct_gather/linux with OverMemoryKill kills a step that outgrows its --mem.
# select/cons_tres with CR_Core_Memory schedules by cores and --mem; EnforcePartLimits=ALL
# refuses at submit a job asking for more CPUs or memory than the node has (by default a job
# with too many CPUs pends for ever, and `sbatch --wait` with it).
set -euo pipefail

DIR="${VAGSL_SLURM_DIR:-/tmp/vagsl-slurm}"
CTLD_PORT="${VAGSL_SLURM_PORT:-6917}"
SLURMD_PORT=$((CTLD_PORT + 1))
START_TIMEOUT="${VAGSL_SLURM_TIMEOUT:-60}"
# A requeued job waits cred_expire seconds before it may start again (120 by default); on one
# local node 10 s is enough for a step's credential and keeps requeue tests short.
CRED_EXPIRE=10
CONF="$DIR/etc/slurm.conf"
MARK="# Written by vagsl scripts/slurm-local.sh"
export SLURM_CONF="$CONF"

die() { echo "slurm-local: error: $*" >&2; exit 1; }
say() { echo "slurm-local: $*" >&2; }

usage() {
  sed -n '5,9p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
}

# Re-runs this script as root: slurmd must be root to start jobs as their users.
as_root() {
  if [ "$(id -u)" != "0" ]; then
    command -v sudo >/dev/null 2>&1 || die "must run as root (no sudo found)"
    exec sudo env VAGSL_SLURM_DIR="$DIR" VAGSL_SLURM_PORT="$CTLD_PORT" \
      VAGSL_SLURM_TIMEOUT="$START_TIMEOUT" bash "$0" "$@"
  fi
}

# Whether the process in pid file $1 is alive and its command is $2.
alive() {
  local pid
  [ -s "$1" ] || return 1
  pid="$(cat "$1")"
  [ -r "/proc/$pid/comm" ] && [ "$(cat "/proc/$pid/comm")" = "$2" ]
}

# The node's state as sinfo reports it (idle, mixed, down*, …), empty when nobody answers.
node_state() {
  timeout 10 sinfo -h -N -n localhost -o '%T' 2>/dev/null | head -n 1 || true
}

# When the registered slurmd started, in seconds since the epoch (0 when unknown).
slurmd_started() {
  local t
  t="$(timeout 10 scontrol -o show node localhost 2>/dev/null | sed -n 's/.*SlurmdStartTime=\([^ ]*\).*/\1/p')"
  date -d "$t" +%s 2>/dev/null || echo 0
}

is_up() {
  alive "$DIR/run/munged.pid" munged && alive "$DIR/run/slurmctld.pid" slurmctld &&
    alive "$DIR/run/slurmd.pid" slurmd && case "$(node_state)" in idle | mixed | allocated) true ;; *) false ;; esac
}

# Memory for the node in MiB: MemTotal (or a smaller cgroup limit) less a margin of a tenth,
# at most 1 GiB, so that slurmd's own count never falls below it.
node_memory_mib() {
  local total limit margin
  total=$(($(awk '/^MemTotal:/ {print $2}' /proc/meminfo) / 1024))
  for f in /sys/fs/cgroup/memory.max /sys/fs/cgroup/memory/memory.limit_in_bytes; do
    if [ -r "$f" ] && limit="$(cat "$f")" && [[ "$limit" =~ ^[0-9]+$ ]]; then
      limit=$((limit / 1048576))
      [ "$limit" -lt "$total" ] && total=$limit
    fi
  done
  margin=$((total / 10))
  [ "$margin" -gt 1024 ] && margin=1024
  echo $((total - margin))
}

# Writes the config to file $1.
write_conf() {
  local cpus mem
  cpus="$(nproc)"
  mem="$(node_memory_mib)"
  cat >"$1" <<EOF
$MARK (rewritten on each start).
# A one-node cluster on localhost; see the script for why each choice.
ClusterName=vagsl-local
SlurmctldHost=localhost
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$DIR/run/munge.socket,cred_expire=$CRED_EXPIRE
StateSaveLocation=$DIR/state/ctld
SlurmdSpoolDir=$DIR/state/d
SlurmctldPidFile=$DIR/run/slurmctld.pid
SlurmdPidFile=$DIR/run/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
SlurmdParameters=config_overrides
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
DefMemPerCPU=$((mem / cpus))
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherFrequency=task=2
JobAcctGatherParams=OverMemoryKill
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$DIR/log/jobcomp.log
ReturnToService=2
EnforcePartLimits=ALL
KillWait=5
InactiveLimit=0
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=main Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
}

start_munged() {
  alive "$DIR/run/munged.pid" munged && return 0
  if [ ! -s "$DIR/etc/munge.key" ]; then
    if command -v mungekey >/dev/null 2>&1; then
      mungekey --create --keyfile="$DIR/etc/munge.key"
    else
      dd if=/dev/urandom of="$DIR/etc/munge.key" bs=1024 count=1 status=none
    fi
  fi
  chmod 0400 "$DIR/etc/munge.key"
  rm -f "$DIR/run/munge.socket" "$DIR/run/munge.socket.lock"
  # --force: munged runs as root here, and its folders sit under /tmp.
  munged --force --socket="$DIR/run/munge.socket" --key-file="$DIR/etc/munge.key" \
    --pid-file="$DIR/run/munged.pid" --log-file="$DIR/log/munged.log" \
    --seed-file="$DIR/state/munged.seed" ||
    die "munged did not start; its log: $(tail -n 20 "$DIR/log/munged.log" 2>/dev/null)"
}

tails() {
  for f in munged slurmctld slurmd; do
    echo "--- $DIR/log/$f.log (last 20 lines) ---" >&2
    tail -n 20 "$DIR/log/$f.log" >&2 2>/dev/null || echo "(none)" >&2
  done
}

start() {
  local p
  for p in slurmctld slurmd sinfo munged; do
    command -v "$p" >/dev/null 2>&1 ||
      die "needs slurmctld, slurmd, sinfo and munged; $p is missing (Debian: apt-get install slurm-wlm munge)"
  done
  if [ -e "$CONF" ] && ! head -n 1 "$CONF" | grep -qF "$MARK"; then
    die "$CONF exists and was not written by this script; set VAGSL_SLURM_DIR to another folder"
  fi
  # Clients (tests run as any user) read slurm.conf and talk to munged's socket, and a job
  # runs its script from slurmd's spool as its user; the key and slurmctld's state stay root's.
  mkdir -p "$DIR/etc" "$DIR/run" "$DIR/log" "$DIR/state/ctld" "$DIR/state/d"
  chmod 0755 "$DIR" "$DIR/etc" "$DIR/run" "$DIR/log" "$DIR/state" "$DIR/state/d"
  chmod 0700 "$DIR/state/ctld"
  write_conf "$CONF.new"
  if is_up && cmp -s "$CONF.new" "$CONF"; then
    rm -f "$CONF.new"
    say "already up (SLURM_CONF=$CONF)"
    return 0
  fi
  # A half-started cluster (one daemon died) or a changed config: restart all three.
  stop
  mv "$CONF.new" "$CONF"
  start_munged
  slurmctld -f "$CONF" -i || { tails; die "slurmctld did not start"; }
  local since state d
  since="$(date +%s)"
  slurmd -f "$CONF" -N localhost || { tails; die "slurmd did not start"; }
  # Up once the new slurmd has registered (slurmctld may report a node state it saved before)
  # and the node takes jobs; a daemon that died (e.g. its port is taken) fails at once.
  while :; do
    state="$(node_state)"
    case "$state" in
      idle | mixed | allocated) [ "$(slurmd_started)" -ge "$since" ] && break ;;
    esac
    # (After 2 s: a daemon that forked may not have written its pid file yet.)
    if [ $(($(date +%s) - since)) -ge 2 ]; then
      for d in munged slurmctld slurmd; do
        alive "$DIR/run/$d.pid" "$d" || { tails; die "$d exited during start; the daemon logs are above"; }
      done
    fi
    if [ $(($(date +%s) - since)) -ge "$START_TIMEOUT" ]; then
      tails
      timeout 10 sinfo -R >&2 2>/dev/null || true
      die "the node is not idle after ${START_TIMEOUT} s (state: '${state:-no answer from slurmctld}'); the daemon logs are above"
    fi
    sleep 1
  done
  local waited=$(($(date +%s) - since))
  say "up after ${waited} s: node localhost, $(nproc) CPUs, $(node_memory_mib) MiB; logs in $DIR/log"
  say "clients need: export SLURM_CONF=$CONF"
}

# Sends TERM to the daemon in pid file $1 (command $2) and waits up to 15 s for it to exit.
stop_one() {
  alive "$1" "$2" || { rm -f "$1"; return 0; }
  local pid
  pid="$(cat "$1")"
  kill "$pid" 2>/dev/null || true
  for _ in $(seq 1 30); do
    alive "$1" "$2" || break
    sleep 0.5
  done
  if alive "$1" "$2"; then kill -9 "$pid" 2>/dev/null || true; fi
  rm -f "$1"
}

stop_daemons() {
  stop_one "$DIR/run/slurmd.pid" slurmd
  stop_one "$DIR/run/slurmctld.pid" slurmctld
  stop_one "$DIR/run/munged.pid" munged
}

stop() {
  if alive "$DIR/run/slurmctld.pid" slurmctld; then
    # Cancel this cluster's jobs first so that no job step outlives slurmd.
    timeout 10 scancel --full --user=root >/dev/null 2>&1 || true
    local users u
    users="$(timeout 10 squeue -h -o '%u' 2>/dev/null | sort -u || true)"
    for u in $users; do timeout 10 scancel --full --user="$u" >/dev/null 2>&1 || true; done
    for _ in $(seq 1 20); do
      [ -z "$(timeout 10 squeue -h -o '%i' 2>/dev/null || true)" ] && break
      sleep 0.5
    done
  fi
  stop_daemons
}

status() {
  if is_up; then
    echo "up: node localhost $(node_state) (SLURM_CONF=$CONF)"
    return 0
  fi
  local d parts=()
  for d in munged slurmctld slurmd; do
    if alive "$DIR/run/$d.pid" "$d"; then parts+=("$d running"); else parts+=("$d not running"); fi
  done
  echo "down: ${parts[*]}; node state '$(node_state)' (start with scripts/slurm-local.sh start)"
  return 3
}

case "${1:-}" in
  start) as_root "$@"; start ;;
  stop) as_root "$@"; stop; say "stopped" ;;
  status) status ;;
  env) echo "export SLURM_CONF=$CONF" ;;
  *) usage ;;
esac
