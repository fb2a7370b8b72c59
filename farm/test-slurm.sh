#!/usr/bin/env bash
# End-to-end test of farm rendering on a real, one-node Slurm cluster.
#
#   bash farm/test-slurm.sh        (as root; .ci/run runs it after cargo test)
#
# 1. Installs Slurm and MUNGE from Debian's packages (slurm-wlm, munge) if
#    they are not there. Not root, no apt-get, or a failed install: it says
#    SKIPPED, loudly, and exits 0.
# 2. Starts a one-node cluster on 127.0.0.1 in a temporary directory:
#    munged (own key and socket), slurmctld and slurmd, with a minimal
#    slurm.conf written here (free ports, proctrack/linuxproc, no cgroups,
#    no accounting). Nothing outside the temporary directory is configured.
# 3. Submits, with farm/submit.sh, a 4-shard array plus the merge job for
#    the Cornell box (64x64, 64 spp unless WT_TEST_SIZE / WT_TEST_SPP say
#    otherwise), and checks that the merged PNG and the merged partial file
#    equal those of a local single run byte for byte.
# 4. Deletes shard 2's partial file, reruns that shard alone
#    (farm/submit.sh --array 2) with a new merge, and checks again.
# 5. Renders a small `wavetrace views` job (farm/views.sbatch, 3 shards) and
#    checks its files equal those of a local single run byte for byte.
# 6. Prints the time of the 4-shard array (submission to the last shard done,
#    and to the merge done) and of the single local run.
# Every wait is bounded. On exit, success or not, it cancels its jobs and
# stops the daemons it started, by PID, and removes the temporary directory
# (kept when WT_KEEP_TMP=1).
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
SIZE=${WT_TEST_SIZE:-64}
SPP=${WT_TEST_SPP:-64}
SHARDS=4
NODE=wtnode
export PATH=$PATH:/usr/sbin:/sbin

say() { echo "test-slurm: $*"; }
skip() {
    echo
    echo "################################################################"
    echo "##  SKIPPED: the Slurm farm test did not run:"
    echo "##  $*"
    echo "################################################################"
    echo "slurm-farm: 0 passed, 0 failed, 1 skipped"
    exit 0
}

# --- 1. Slurm and MUNGE -------------------------------------------------------
# The cluster runs its daemons and jobs as root (SlurmUser=root).
[ "$(id -u)" = 0 ] || skip "not root: cannot install slurm-wlm and munge or run slurmctld and slurmd as SlurmUser=root"
missing=()
for tool in munged slurmctld slurmd sbatch squeue sinfo scontrol scancel; do
    command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
done
if [ ${#missing[@]} -gt 0 ]; then
    command -v apt-get >/dev/null 2>&1 || skip "no apt-get, cannot install slurm-wlm and munge"
    say "installing slurm-wlm and munge (missing: ${missing[*]})"
    export DEBIAN_FRONTEND=noninteractive
    apt_install() {
        timeout 900 apt-get -q -o DPkg::Lock::Timeout=300 install -y --no-install-recommends \
            slurm-wlm munge >>/tmp/wavetrace-slurm-apt.log 2>&1
    }
    if ! apt_install; then
        timeout 600 apt-get -q -o DPkg::Lock::Timeout=300 update >>/tmp/wavetrace-slurm-apt.log 2>&1
        apt_install || {
            tail -n 20 /tmp/wavetrace-slurm-apt.log
            skip "apt-get install slurm-wlm munge failed (log: /tmp/wavetrace-slurm-apt.log)"
        }
    fi
    for tool in "${missing[@]}"; do
        command -v "$tool" >/dev/null 2>&1 || skip "$tool is still missing after installing slurm-wlm and munge"
    done
fi
say "$(slurmctld -V 2>&1 | head -n1), munge $(munged -V 2>&1 | head -n1)"

# --- the binary -------------------------------------------------------------
say "building wavetrace (release)"
cargo build --release --quiet --bin wavetrace || { echo "slurm-farm: 0 passed, 1 failed"; exit 1; }
BIN=$ROOT/target/release/wavetrace

# --- 2. the cluster, torn down on any exit ----------------------------------
T=$(mktemp -d /tmp/wavetrace-slurm.XXXXXX)
chmod 700 "$T"
MUNGED_PID= SLURMCTLD_PID= SLURMD_PID=
JOBS=()

stop_pid() { # stop_pid NAME PID: TERM, up to 10 s, then KILL
    local name=$1 pid=$2 i
    [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null || return 0
    kill -TERM "$pid" 2>/dev/null
    for ((i = 0; i < 50; i++)); do
        kill -0 "$pid" 2>/dev/null || { wait "$pid" 2>/dev/null; say "stopped $name (pid $pid)"; return 0; }
        sleep 0.2
    done
    kill -KILL "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
    say "killed $name (pid $pid) after 10 s"
}
cleanup() {
    local rc=$?
    set +e
    trap - EXIT INT TERM
    if [ ${#JOBS[@]} -gt 0 ] && [ -n "$SLURMCTLD_PID" ] && kill -0 "$SLURMCTLD_PID" 2>/dev/null; then
        timeout 10 scancel "${JOBS[@]}" 2>/dev/null
        # Let slurmd end the job steps it started before it stops.
        for ((i = 0; i < 25; i++)); do
            [ -z "$(timeout 5 squeue -h -o %i 2>/dev/null)" ] && break
            sleep 0.2
        done
    fi
    stop_pid slurmd "$SLURMD_PID"
    stop_pid slurmctld "$SLURMCTLD_PID"
    stop_pid munged "$MUNGED_PID"
    if [ "${WT_KEEP_TMP:-0}" = 1 ]; then say "kept $T"; else rm -rf "$T"; fi
    # The verdict comes last, after the daemons are stopped.
    if [ "$rc" = 0 ]; then
        echo "slurm-farm: 1 passed, 0 failed"
    else
        echo "slurm-farm: 0 passed, 1 failed"
    fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

show_logs() {
    local f
    for f in "$T"/munged.log "$T"/slurmctld.log "$T"/slurmd.log "$T"/parts/*.log "$T"/*.out; do
        [ -f "$f" ] || continue
        echo "----- $f (last 30 lines)"
        tail -n 30 "$f"
    done
}
fail() {
    echo "test-slurm: FAILED: $*"
    show_logs
    exit 1
}

# wait_for SECONDS WHAT COMMAND...: poll COMMAND every 0.2 s until it succeeds.
wait_for() {
    local limit=$1 what=$2 deadline
    shift 2
    deadline=$((SECONDS + limit))
    until "$@"; do
        [ $SECONDS -lt $deadline ] || fail "timed out after ${limit} s waiting for $what"
        sleep 0.2
    done
}

# Two free TCP ports on 127.0.0.1.
free_port() {
    local p
    for ((i = 0; i < 200; i++)); do
        p=$((20000 + RANDOM % 40000))
        if ! (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then
            echo "$p"
            return
        fi
    done
    fail "no free port"
}
CTLD_PORT=$(free_port)
SLURMD_PORT=$(free_port)
while [ "$SLURMD_PORT" = "$CTLD_PORT" ]; do SLURMD_PORT=$(free_port); done
HOST=$(hostname -s)
CPUS=$(nproc)

# MUNGE: a fresh key and socket of our own.
dd if=/dev/urandom of="$T/munge.key" bs=1024 count=1 status=none
chmod 400 "$T/munge.key"
munged --foreground --force --key-file="$T/munge.key" --socket="$T/munge.socket" \
    --pid-file="$T/munged.pid" --log-file="$T/munged.log" --seed-file="$T/munged.seed" \
    >"$T/munged.out" 2>&1 &
MUNGED_PID=$!
say "started munged (pid $MUNGED_PID)"
wait_for 20 "munged's socket" test -S "$T/munge.socket"
kill -0 "$MUNGED_PID" 2>/dev/null || fail "munged exited"

mkdir -p "$T/state" "$T/spool" "$T/parts"
cat >"$T/slurm.conf" <<CONF
# A one-node cluster for wavetrace's farm test; written by farm/test-slurm.sh.
ClusterName=wavetrace-test
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$T/munge.socket
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/slurmctld.log
SlurmdLogFile=$T/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MinJobAge=600
NodeName=$NODE NodeHostname=$HOST NodeAddr=127.0.0.1 CPUs=$CPUS State=UNKNOWN
PartitionName=test Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$T/slurm.conf
# Our environment must not leak into the jobs' shard index.
unset SLURM_ARRAY_TASK_ID SLURM_CPUS_PER_TASK JOB_COMPLETION_INDEX

slurmctld -D -c -f "$SLURM_CONF" >"$T/slurmctld.out" 2>&1 &
SLURMCTLD_PID=$!
say "started slurmctld (pid $SLURMCTLD_PID, port $CTLD_PORT)"
ctld_up() {
    kill -0 "$SLURMCTLD_PID" 2>/dev/null || fail "slurmctld exited"
    timeout 5 scontrol ping >"$T/ping.out" 2>&1 && grep -q UP "$T/ping.out"
}
wait_for 30 "slurmctld to answer" ctld_up
slurmd -D -f "$SLURM_CONF" -N "$NODE" >"$T/slurmd.out" 2>&1 &
SLURMD_PID=$!
say "started slurmd (pid $SLURMD_PID, port $SLURMD_PORT)"
node_idle() {
    kill -0 "$SLURMD_PID" 2>/dev/null || fail "slurmd exited"
    kill -0 "$SLURMCTLD_PID" 2>/dev/null || fail "slurmctld exited"
    [ "$(timeout 5 sinfo -h -n "$NODE" -o %T 2>/dev/null)" = idle ]
}
wait_for 60 "node $NODE to be idle" node_idle
say "cluster up: node $NODE with $CPUS CPUs, $(sinfo -h -o '%P %a %D %T')"

# --- 3. the farm render and the single run -------------------------------------
RENDER_ARGS=(--width "$SIZE" --height "$SIZE" --spp "$SPP" --seed 7)
now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }

job_state() { timeout 5 scontrol -o show job "$1" 2>/dev/null | tr ' ' '\n' | sed -n 's/^JobState=//p' | sort -u | tr '\n' ' '; }
# jobs_done ID: no task of job ID is pending or running any more.
jobs_done() {
    local states
    states=$(job_state "$1")
    [ -n "$states" ] && ! grep -qE 'PENDING|RUNNING|CONFIGURING|COMPLETING|REQUEUED|RESIZING|SUSPENDED' <<<"$states"
}
# run_farm LABEL SUBMIT_ARGS...: submit, wait, check every job COMPLETED.
run_farm() {
    local label=$1 out array merge t0 t1 t2
    shift
    t0=$(now)
    out=$(WAVETRACE=$BIN timeout 60 farm/submit.sh --shards "$SHARDS" --parts "$T/parts" \
        --out "$T/merged.png" --partial "$T/merged.wtacc" "$@" -- "${RENDER_ARGS[@]}") ||
        fail "farm/submit.sh failed: $out"
    array=$(sed -n 's/^array //p' <<<"$out")
    merge=$(sed -n 's/^merge //p' <<<"$out")
    [ -n "$array" ] && [ -n "$merge" ] || fail "farm/submit.sh printed no job IDs: $out"
    JOBS+=("$array" "$merge")
    say "$label: submitted array job $array and merge job $merge (afterok:$array)"
    wait_for 300 "array job $array" jobs_done "$array"
    t1=$(now)
    wait_for 300 "merge job $merge" jobs_done "$merge"
    t2=$(now)
    [ "$(job_state "$array")" = "COMPLETED " ] || fail "array job $array ended $(job_state "$array")"
    [ "$(job_state "$merge")" = "COMPLETED " ] || fail "merge job $merge ended $(job_state "$merge")"
    ARRAY_SECONDS=$(elapsed "$t0" "$t1")
    FARM_SECONDS=$(elapsed "$t0" "$t2")
}

t0=$(now)
"$BIN" render "${RENDER_ARGS[@]}" --threads "$CPUS" --out "$T/single.png" --partial "$T/single.wtacc" \
    >"$T/single.out" 2>&1 || fail "the single local run failed: $(cat "$T/single.out")"
SINGLE_SECONDS=$(elapsed "$t0" "$(now)")

run_farm "4-shard farm render"
say "merge log: $(tail -n 1 "$T/parts/merge.log")"
check_identical() {
    cmp "$T/merged.png" "$T/single.png" || fail "$1: the merged PNG differs from the single run's"
    cmp "$T/merged.wtacc" "$T/single.wtacc" || fail "$1: the merged partial file differs from the single run's"
    say "$1: merged == single run, byte for byte: $(sha256sum <"$T/merged.png" | cut -c1-16) $(basename "$T/merged.png"), $(sha256sum <"$T/merged.wtacc" | cut -c1-16) $(basename "$T/merged.wtacc")"
}
check_identical "4-shard array"
FIRST_ARRAY=$ARRAY_SECONDS FIRST_FARM=$FARM_SECONDS
# The shards ran with --cpus-per-task=1: SLURM_CPUS_PER_TASK set their threads
# (the shards' stats files say; a batch job prints no banner).
grep -q '"threads": 1,' "$T/parts/part-0.json" || fail "shard 0 did not run 1 thread (SLURM_CPUS_PER_TASK=1)"
grep -q '"shard": \[' "$T/parts/part-0.json" || fail "shard 0's stats name no shard"
say "shard 0 log: $(tail -n 1 "$T/parts/shard-0.log")"
# The shards' own render times, from their stats, apart from Slurm's scheduling.
SHARD_TIMES=$(sed -n 's/^  "seconds": \([0-9.e+-]*\),$/\1/p' "$T"/parts/part-*.json |
    awk '{ s += $1; if ($1 > m) m = $1; n++ } END { printf "sum %.2f s, longest %.2f s (%d shards)", s, m, n }')

# --- 4. a failed shard, rerun alone -------------------------------------------------
rm -f "$T/parts/part-2.wtacc" "$T/merged.png" "$T/merged.wtacc"
if "$BIN" merge "$T"/parts/part-{0..3}.wtacc --out "$T/merged.png" >"$T/lost.out" 2>&1; then
    fail "merge succeeded without part 2"
fi
[ ! -e "$T/merged.png" ] || fail "a refused merge wrote $T/merged.png"
say "without part 2, merge refuses: $(head -n 1 "$T/lost.out")"
run_farm "rerun of shard 2" --array 2
check_identical "shard 2 rerun + merge"

# --- 5. a views dataset job across shards ------------------------------------
cat >"$T/views-job.toml" <<VJOB
[assets]
files = ["$ROOT/scenes/textured.glb"]
normalize = true
[cameras]
kind = "orbit"
views = 4
elevations = [20.0, 45.0]
[render]
width = 32
height = 32
spp = 8
[outputs]
aov = ["depth"]
VJOB
"$BIN" views "$T/views-job.toml" --out-dir "$T/views-single" --threads "$CPUS" >"$T/views-single.out" 2>&1 ||
    fail "the single views run failed: $(cat "$T/views-single.out")"
mkdir -p "$T/views-logs"
views_array=$(WAVETRACE=$BIN timeout 60 sbatch --parsable --array=0-2 --cpus-per-task=1 \
    --output="$T/views-logs/views-%a.log" farm/views.sbatch 3 "$T/views-job.toml" "$T/views-farm") ||
    fail "sbatch farm/views.sbatch failed: $views_array"
views_array=${views_array%%;*}
JOBS+=("$views_array")
say "views: submitted 3-shard array job $views_array"
wait_for 300 "views array job $views_array" jobs_done "$views_array"
[ "$(job_state "$views_array")" = "COMPLETED " ] || fail "views array job $views_array ended $(job_state "$views_array")"
rm -f "$T"/views-farm/stats-*.json
diff -r "$T/views-single" "$T/views-farm" >/dev/null || fail "the 3-shard views job's files differ from the single run's"
say "views: 3-shard Slurm array == single run, byte for byte ($(find "$T/views-farm" -type f | wc -l) files)"

# --- 6. times ------------------------------------------------------------------
echo
echo "test-slurm: Cornell box ${SIZE}x${SIZE}, ${SPP} spp, seed 7, one node with $CPUS CPUs:"
echo "test-slurm:   single local run (--threads $CPUS):                              ${SINGLE_SECONDS} s"
echo "test-slurm:   4-shard Slurm array (1 CPU each), submit to last shard done: ${FIRST_ARRAY} s"
echo "test-slurm:   4-shard Slurm array + merge job, submit to merged image:     ${FIRST_FARM} s"
echo "test-slurm:   the shards' own render time (from their stats): ${SHARD_TIMES};"
echo "test-slurm:   the rest is Slurm's scheduling and job launch (a scheduler pass every few seconds)"
