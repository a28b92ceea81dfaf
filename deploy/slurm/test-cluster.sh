#!/usr/bin/env bash
# A throwaway one-node Slurm cluster for tests and demos, built from Debian
# 12's slurm-wlm and munge packages. Everything it writes (munge key, configs,
# state, spool, logs, pid files, the munge socket) lives under one directory,
# and its ports are picked free, so several clusters (and a system Slurm) can
# run side by side.
#
#   test-cluster.sh start DIR   start munged, slurmctld and slurmd for DIR;
#                               prints SLURM_CONF=... (for eval) on stdout
#   test-cluster.sh stop DIR    stop what `start DIR` started (idempotent)
#
# Progress and errors go to stderr; stdout carries only the assignments.
# Not a production setup: it runs everything as root on one host.
set -euo pipefail

prog=test-cluster.sh
start_timeout=${REENACT_SLURM_START_TIMEOUT:-30}  # seconds until the node is idle
stop_grace=5                                      # seconds between SIGTERM and SIGKILL

die() {
  echo "$prog: error: $*" >&2
  exit 1
}
note() { echo "$prog: $*" >&2; }

usage() {
  echo "usage: $prog start DIR | stop DIR" >&2
  exit 2
}

# --- process helpers ---------------------------------------------------------

# Succeeds when PID is a live (not zombie) munged, slurmctld or slurmd whose
# command line contains the argument MARKER; that is how the script recognises
# the daemons it started and leaves any other process (a reused pid, a system
# daemon, another cluster's daemon) alone.
is_ours() {
  local pid=$1 marker=$2 state cmdline
  [[ $pid =~ ^[0-9]+$ ]] || return 1
  [ -r "/proc/$pid/stat" ] || return 1
  state=$(sed -E 's/^.*\) ([A-Za-z]).*$/\1/' "/proc/$pid/stat" 2>/dev/null) || return 1
  [ "$state" != Z ] && [ "$state" != X ] || return 1
  cmdline=$(tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null) || return 1
  [[ $cmdline =~ ^([^ ]*/)?(munged|slurmctld|slurmd)\  ]] && [[ $cmdline == *" $marker "* ]]
}

read_pid() {
  if [ -s "$1" ]; then
    head -n1 "$1" | tr -dc '0-9'
  fi
  return 0
}

# Stops the process in pid file FILE if it is ours (MARKER in its command
# line): SIGTERM, then SIGKILL after GRACE (default $stop_grace) seconds.
stop_pidfile() {
  local name=$1 file=$2 marker=$3 grace=${4:-$stop_grace} pid i
  pid=$(read_pid "$file")
  if [ -n "$pid" ] && is_ours "$pid" "$marker"; then
    kill -TERM "$pid" 2>/dev/null || true
    for ((i = 0; i < grace * 10; i++)); do
      is_ours "$pid" "$marker" || break
      sleep 0.1
    done
    if is_ours "$pid" "$marker"; then
      note "$name (pid $pid) ignored SIGTERM; sending SIGKILL"
      kill -KILL "$pid" 2>/dev/null || true
      for ((i = 0; i < 20; i++)); do
        is_ours "$pid" "$marker" || break
        sleep 0.1
      done
    fi
  fi
  rm -f "$file"
}

# Kills PID and all its descendants (children first is not needed: SIGKILL).
kill_tree() {
  local pid=$1 child
  for child in $(ps -o pid= --ppid "$pid" 2>/dev/null); do
    kill_tree "$child"
  done
  kill -KILL "$pid" 2>/dev/null || true
}

# --- paths -------------------------------------------------------------------

set_paths() {
  dir=$1
  conf=$dir/slurm.conf
  munge_socket=$dir/munge.socket
  munge_key=$dir/munge/munge.key
  munge_seed=$dir/munge/munged.seed
  state_dir=$dir/state
  spool_dir=$dir/spool
  log_dir=$dir/log
  run_dir=$dir/run
  munged_pid=$run_dir/munged.pid
  slurmctld_pid=$run_dir/slurmctld.pid
  slurmd_pid=$run_dir/slurmd.pid
  # What the daemons' command lines contain (see is_ours).
  munged_marker="--socket=$munge_socket"
  slurm_marker="-f $conf"
}

show_logs() {
  local f
  for f in "$log_dir"/munged.log "$log_dir"/slurmctld.log "$log_dir"/slurmctld.stderr \
    "$log_dir"/slurmd.log "$log_dir"/slurmd.stderr; do
    if [ -s "$f" ]; then
      echo "---- last lines of $f ----" >&2
      tail -n 20 "$f" >&2
    fi
  done
}

# --- configuration -----------------------------------------------------------

# Prints two distinct TCP ports that nothing on this host uses, below the
# ephemeral range (so that client connections cannot take them meanwhile).
pick_ports() {
  local used=" " line port lo=10000 hi=32000 eph_lo n=0 candidate
  if read -r eph_lo _ </proc/sys/net/ipv4/ip_local_port_range 2>/dev/null &&
    [ "$eph_lo" -gt $((lo + 2000)) ] && [ "$eph_lo" -lt "$hi" ]; then
    hi=$eph_lo
  fi
  for f in /proc/net/tcp /proc/net/tcp6; do
    [ -r "$f" ] || continue
    while read -r _ line _; do
      port=${line##*:}
      [[ $port =~ ^[0-9A-Fa-f]{4}$ ]] && used+="$((16#$port)) "
    done <"$f"
  done
  local picked=()
  while [ ${#picked[@]} -lt 2 ]; do
    ((++n > 1000)) && die "found no free TCP port in $lo-$hi"
    candidate=$((lo + (RANDOM * 32768 + RANDOM) % (hi - lo)))
    [[ $used == *" $candidate "* ]] && continue
    [ ${#picked[@]} -eq 1 ] && [ "${picked[0]}" -eq "$candidate" ] && continue
    picked+=("$candidate")
  done
  echo "${picked[@]}"
}

# The node's hardware line for slurm.conf: what slurmd itself detects (so the
# node never comes up as INVALID), else nproc and free.
node_hardware() {
  local line
  if line=$(slurmd -C 2>/dev/null | grep -m1 '^NodeName='); then
    line=$(tr ' ' '\n' <<<"$line" | grep -E '^(CPUs|Boards|SocketsPerBoard|CoresPerSocket|ThreadsPerCore|RealMemory)=' | tr '\n' ' ')
    if [[ $line == *CPUs=* && $line == *RealMemory=* ]]; then
      echo "${line% }"
      return
    fi
  fi
  echo "CPUs=$(nproc) RealMemory=$(free -m | awk '/^Mem:/ {print $2}')"
}

select_type() {
  local plugin_dirs=(/usr/lib/*/slurm-wlm /usr/lib/slurm-wlm /usr/lib*/slurm)
  local d
  for d in "${plugin_dirs[@]}"; do
    [ -e "$d/select_cons_tres.so" ] && { echo select/cons_tres; return; }
  done
  for d in "${plugin_dirs[@]}"; do
    [ -e "$d/select_linear.so" ] && { echo select/linear; return; }
  done
  echo select/cons_tres
}

write_conf() {
  local ctld_port=$1 slurmd_port=$2 select
  select=$(select_type)
  {
    echo "# One-node test cluster written by deploy/slurm/test-cluster.sh."
    echo "# Not for production use."
    echo "ClusterName=reenact"
    echo "SlurmctldHost=$node(127.0.0.1)"
    echo "SlurmctldPort=$ctld_port"
    echo "SlurmdPort=$slurmd_port"
    echo "AuthType=auth/munge"
    echo "CredType=cred/munge"
    echo "AuthInfo=socket=$munge_socket"
    echo "SlurmUser=root"
    echo "SlurmdUser=root"
    echo "StateSaveLocation=$state_dir"
    echo "SlurmdSpoolDir=$spool_dir"
    echo "SlurmctldPidFile=$slurmctld_pid"
    echo "SlurmdPidFile=$slurmd_pid"
    echo "SlurmctldLogFile=$log_dir/slurmctld.log"
    echo "SlurmdLogFile=$log_dir/slurmd.log"
    echo "SlurmctldDebug=info"
    echo "SlurmdDebug=info"
    echo "SelectType=$select"
    [ "$select" = select/cons_tres ] && echo "SelectTypeParameters=CR_CPU"
    echo "ProctrackType=proctrack/linuxproc"
    echo "TaskPlugin=task/none"
    echo "JobAcctGatherType=jobacct_gather/none"
    echo "AccountingStorageType=accounting_storage/none"
    echo "JobCompType=jobcomp/none"
    echo "MpiDefault=none"
    echo "ReturnToService=2"
    echo "PropagateResourceLimits=NONE"
    echo "MailProg=/bin/true"
    echo "KillWait=5"
    echo "NodeName=$node NodeAddr=127.0.0.1 NodeHostname=$node $hardware State=UNKNOWN"
    echo "PartitionName=reenact Nodes=$node Default=YES MaxTime=INFINITE State=UP"
  } >"$conf.tmp"
  mv "$conf.tmp" "$conf"
}

# --- start -------------------------------------------------------------------

check_prerequisites() {
  [ "$(id -u)" -eq 0 ] || die "must run as root (the daemons run as root)"
  local missing=() tool
  for tool in munged slurmctld slurmd sinfo squeue scancel; do
    command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
  done
  if ! command -v mungekey >/dev/null 2>&1 && ! command -v dd >/dev/null 2>&1; then
    missing+=(mungekey)
  fi
  [ ${#missing[@]} -eq 0 ] ||
    die "missing ${missing[*]}; install Debian's packages: apt-get install slurm-wlm munge (or run deploy/setup-debian.sh)"
}

daemons_running() {
  is_ours "$(read_pid "$munged_pid")" "$munged_marker" ||
    is_ours "$(read_pid "$slurmctld_pid")" "$slurm_marker" ||
    is_ours "$(read_pid "$slurmd_pid")" "$slurm_marker"
}

start_munged() {
  rm -f "$munge_socket" "$munge_socket.lock" "$munged_pid"
  # --force: munged insists that every directory above its socket be
  # searchable by everyone; test directories (mktemp -d, 0700) are not, and
  # only root talks to this munged anyway.
  if ! munged --force --socket="$munge_socket" --key-file="$munge_key" \
    --pid-file="$munged_pid" --log-file="$log_dir/munged.log" \
    --seed-file="$munge_seed" --num-threads=2 \
    </dev/null >>"$log_dir/munged.stderr" 2>&1; then
    cat "$log_dir/munged.stderr" >&2 || true
    return 1
  fi
  local i
  for ((i = 0; i < 50; i++)); do
    [ -S "$munge_socket" ] && is_ours "$(read_pid "$munged_pid")" "$munged_marker" && return 0
    sleep 0.1
  done
  return 1
}

# Starts slurmctld and slurmd and waits until the node is idle. Returns 0 when
# ready, 2 when a port turned out to be taken (the caller picks others), 1 on
# any other failure.
start_slurm() {
  local name pidfile extra
  for name in slurmctld slurmd; do
    pidfile=$slurmctld_pid
    extra=()
    [ $name = slurmd ] && { pidfile=$slurmd_pid; extra=(-N "$node"); }
    rm -f "$pidfile"
    # The daemons fork into the background themselves; their stdio goes to
    # files so that a caller reading our stdout is not held open by them.
    if ! env SLURM_CONF="$conf" $name -f "$conf" "${extra[@]}" \
      </dev/null >>"$log_dir/$name.stderr" 2>&1; then
      note "$name failed to start"
      return 1
    fi
  done

  local deadline=$((SECONDS + start_timeout)) started=$SECONDS state="" pid
  local logs=("$log_dir"/slurmctld.log "$log_dir"/slurmd.log "$log_dir"/slurmctld.stderr "$log_dir"/slurmd.stderr)
  while ((SECONDS < deadline)); do
    grep -qsi 'address already in use' "${logs[@]}" && return 2
    for name in slurmctld slurmd; do
      pidfile=$slurmctld_pid
      [ $name = slurmd ] && pidfile=$slurmd_pid
      pid=$(read_pid "$pidfile")
      if [ -n "$pid" ] && ! is_ours "$pid" "$slurm_marker"; then
        note "$name exited during startup"
        return 1
      fi
      if [ -z "$pid" ] && ((SECONDS - started > 5)); then
        note "$name wrote no pid file to $pidfile"
        return 1
      fi
    done
    state=$(SLURM_CONF=$conf sinfo -h -N -n "$node" -o %T 2>/dev/null | head -n1) || state=""
    [ "$state" = idle ] && return 0
    sleep 0.2
  done
  note "node $node did not become idle within ${start_timeout}s (last state: ${state:-unknown})"
  return 1
}

cmd_start() {
  check_prerequisites
  mkdir -p "$1"
  set_paths "$(cd "$1" && pwd -P)"
  [[ $dir =~ ^[A-Za-z0-9_./+-]+$ ]] ||
    die "DIR must be a path without spaces or special characters: $dir"
  node=$(hostname -s)
  [ -n "$node" ] || die "hostname -s printed nothing"
  # Unix socket paths are limited to 107 bytes; the longest one is a job
  # step's socket in the spool directory (NODE_JOBID.STEPID).
  if ((${#spool_dir} + ${#node} + 24 > 107)); then
    die "DIR is too long for Unix socket paths (${#dir} bytes); use a shorter one, e.g. mktemp -d /tmp/slurm.XXXXXX"
  fi
  daemons_running && die "a cluster is already running in $dir; run: $prog stop $dir"

  # Fresh state on every start; other files the caller keeps in DIR stay.
  rm -rf "$state_dir" "$spool_dir" "$log_dir" "$run_dir" "$dir/munge"
  mkdir -p "$state_dir" "$spool_dir" "$log_dir" "$run_dir"
  mkdir -m 0700 "$dir/munge"
  if command -v mungekey >/dev/null 2>&1; then
    mungekey --create --keyfile="$munge_key" --force 2>>"$log_dir/munged.stderr"
  else
    dd if=/dev/urandom of="$munge_key" bs=1024 count=1 status=none
  fi
  chmod 0400 "$munge_key"

  hardware=$(node_hardware)

  if ! start_munged; then
    note "munged did not start"
    show_logs
    cmd_stop_quiet
    exit 1
  fi

  local attempt rc ports
  for attempt in 1 2 3 4 5; do
    read -r -a ports <<<"$(pick_ports)"
    write_conf "${ports[0]}" "${ports[1]}"
    rc=0
    start_slurm || rc=$?
    [ $rc -eq 0 ] && break
    # Nothing runs on a cluster that did not come up: no need to wait long.
    stop_pidfile slurmd "$slurmd_pid" "$slurm_marker" 1
    stop_pidfile slurmctld "$slurmctld_pid" "$slurm_marker" 1
    if [ $rc -eq 2 ] && [ $attempt -lt 5 ]; then
      note "port ${ports[0]} or ${ports[1]} was taken meanwhile; trying others"
      mkdir -p "$log_dir/attempt$attempt"
      mv "$log_dir"/slurm*.* "$log_dir/attempt$attempt/" 2>/dev/null || true
      rm -rf "$state_dir" "$spool_dir"
      mkdir -p "$state_dir" "$spool_dir"
      continue
    fi
    note "the cluster in $dir did not come up"
    show_logs
    cmd_stop_quiet
    exit 1
  done

  note "cluster up in $dir: node $node ($hardware), partition reenact," \
    "slurmctld port ${ports[0]}, slurmd port ${ports[1]}"
  printf 'SLURM_CONF=%q\n' "$conf"
}

# --- stop --------------------------------------------------------------------

# Cancels all jobs while slurmctld still runs, so that their slurmstepd and
# job processes end with them; then stops the daemons.
cmd_stop_quiet() {
  local ctld i
  ctld=$(read_pid "$slurmctld_pid")
  if is_ours "$ctld" "$slurm_marker" && [ -f "$conf" ]; then
    local jobs
    jobs=$(SLURM_CONF=$conf timeout 10 squeue -h -o %i 2>/dev/null || true)
    if [ -n "$jobs" ]; then
      # shellcheck disable=SC2086 # one job id per word
      SLURM_CONF=$conf timeout 10 scancel $jobs 2>/dev/null || true
      for ((i = 0; i < 100; i++)); do
        [ -z "$(SLURM_CONF=$conf timeout 10 squeue -h -t R,CG,S -o %i 2>/dev/null || true)" ] && break
        sleep 0.1
      done
    fi
  fi
  stop_pidfile slurmd "$slurmd_pid" "$slurm_marker"
  stop_pidfile slurmctld "$slurmctld_pid" "$slurm_marker"
  kill_leftover_stepds
  stop_pidfile munged "$munged_pid" "$munged_marker"
  rm -f "$munge_socket" "$munge_socket.lock"
}

# A slurmstepd whose slurmd is gone (for example when slurmctld was already
# dead and jobs could not be cancelled) listens on a socket in this cluster's
# spool directory; that identifies it and its job processes as ours.
kill_leftover_stepds() {
  [ -d "$spool_dir" ] && [ -r /proc/net/unix ] || return 0
  local inodes pid fd target
  inodes=$(awk -v p="$spool_dir/" 'index($8, p) == 1 {print $7}' /proc/net/unix | sort -u)
  [ -n "$inodes" ] || return 0
  for pid in $(pgrep -x slurmstepd 2>/dev/null || true); do
    for fd in /proc/"$pid"/fd/*; do
      target=$(readlink "$fd" 2>/dev/null) || continue
      if [[ $target =~ ^socket:\[([0-9]+)\]$ ]] && grep -qx "${BASH_REMATCH[1]}" <<<"$inodes"; then
        note "killing leftover slurmstepd (pid $pid) and its job processes"
        kill_tree "$pid"
        break
      fi
    done
  done
}

cmd_stop() {
  [ "$(id -u)" -eq 0 ] || die "must run as root"
  [ -d "$1" ] || return 0
  set_paths "$(cd "$1" && pwd -P)"
  cmd_stop_quiet
}

[ $# -eq 2 ] || usage
case $1 in
  start) cmd_start "$2" ;;
  stop) cmd_stop "$2" ;;
  *) usage ;;
esac
