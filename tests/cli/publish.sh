#!/usr/bin/env bash
# Durable publishing (stages/lib/io/publish.c), read off the system calls:
# a pipeline with a job of every stage (voxelize with colours, svo-to-dag
# cells and merge, symmetry-merge, lossy-cluster, edit, encode, colorize,
# render) and the runner's own files (report, keys, lists), all under
# strace -f, threads mapped to their processes. For every rename:
#   - what is renamed was fsynced first (under this name, or under an
#     earlier name it was renamed from: a staged pair), or is a staging
#     directory whose name list was fsynced;
#   - the directory it lands in is fsynced after it by the same process,
#     before that process exits (a staging directory before it is swapped
#     in; a staged pair's directory once, after both renames).
# The runner appends a job's key only after the process that published
# the job's output has exited; nothing named *.tmp.* is left.
# Skips (one line) where strace cannot run.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
if ! command -v strace >/dev/null; then
	echo "SKIP publish (needs strace)"
	exit 0
fi
if ! strace -f -o /dev/null true 2>/dev/null; then
	echo "SKIP publish (strace cannot trace here: ptrace not allowed)"
	exit 0
fi
D=$T/out
cat > "$T/p.yaml" <<EOF
version: 1
name: fsync
input: {mesh: $PWD/tests/data/spider/spider.obj}
levels: 7
chunk_level: 1
outputs: $D
resources: {jobs: 2, threads: 2, mem_budget: 2GiB, job_mem_budget: 512M}
jobs:
  vox:    {stage: voxelize}
  dag:    {stage: svo-to-dag, needs: [vox]}
  ssvdag: {stage: symmetry-merge, needs: [dag]}
  enc:    {stage: encode, needs: [dag, ssvdag]}
  col:    {stage: colorize, needs: [vox], method: vbr, max_error: 0.05}
  pic:    {stage: render, needs: [enc, col]}
  lossy:  {stage: lossy-cluster, needs: [dag]}
  ed:     {stage: edit, needs: [dag, vox], script: ["carve box 0 0 0 20 20 20"]}
EOF
strace -f -q -y -s 4096 -o "$T/trace" \
	-e trace=rename,renameat,renameat2,fsync,fdatasync,write,execve,clone,clone3,fork,vfork \
	$R -q run "$T/p.yaml" 2>"$T/err"
rc=$?
if [ $rc -ne 0 ]; then
	fail pipeline_under_strace "exit $rc" "$(head -c 600 "$T/err")"
	exit 0
fi
pass pipeline_under_strace
python3 - "$T/trace" "$PWD" "$D" <<'PY' > "$T/verdict"
import os, re, sys
trace, cwd, outs = sys.argv[1], sys.argv[2], sys.argv[3]
line_re = re.compile(r'^(\d+)\s+(\w+)\((.*)\)\s+=\s+(-?\d+|\?)')
def path(p):
    return os.path.normpath(p if p.startswith('/') else os.path.join(cwd, p))
synced = {}            # pid -> paths fsynced (or renamed from such)
pending = {}           # pid -> {directory: the rename waiting for its fsync}
prog = {}              # pid -> program name
problems, renames, stages = [], 0, set()
exited = set()         # pids that exited
renamer = {}           # path -> the pid that last renamed onto it
keys = 0
partial = {}           # tid -> a call strace split (<unfinished ...>)
tgid = {}              # tid -> its process (thread group)
for line in open(trace):
    line = line.rstrip('\n')
    if line.endswith('<unfinished ...>'):
        partial[line.split()[0]] = line[:-len('<unfinished ...>')].rstrip()
        continue
    r = re.match(r'^(\d+)\s+<\.\.\. \w+ resumed>(.*)$', line)
    if r and r.group(1) in partial:
        line = partial.pop(r.group(1)) + r.group(2)
    m = line_re.match(line)
    if not m:
        if '+++ exited' in line or '+++ killed' in line:
            pid = line.split()[0]
            if tgid.get(pid, pid) != pid:
                continue  # a thread, not its process
            for d, what in pending.pop(pid, {}).items():
                problems.append(f'{prog.get(pid)} {pid}: {what}, then no fsync of {d} before it exited')
            exited.add(pid)
        continue
    tid, call, args, ret = m.groups()
    if ret == '?' or (ret.lstrip('-').isdigit() and int(ret) < 0):
        continue
    pid = tgid.get(tid, tid)  # strace -f names threads: keep processes
    if call in ('clone', 'clone3', 'fork', 'vfork'):
        tgid[ret] = pid if 'CLONE_THREAD' in args else ret
        continue
    if call == 'execve':
        prog[pid] = os.path.basename(re.match(r'"([^"]*)"', args).group(1))
        stages.add(prog[pid])
    elif call in ('fsync', 'fdatasync'):
        p = re.match(r'\d+<(.*)>', args).group(1)
        synced.setdefault(pid, set()).add(p)
        pending.get(pid, {}).pop(p, None)
    elif call.startswith('rename'):
        names = re.findall(r'"((?:[^"\\]|\\.)*)"', args)
        a, b = path(names[0]), path(names[1])
        renames += 1
        what = f'{call} {a} -> {b}'
        s = synced.setdefault(pid, set())
        if a not in s:
            problems.append(f'{prog.get(pid)} {pid}: {what} before any fsync of {a}')
        s.discard(a)
        s.add(b)
        if 'RENAME_EXCHANGE' in args:
            s.add(a)
        pending.setdefault(pid, {})[os.path.dirname(b)] = what
        renamer[b] = pid
    elif call == 'write' and re.match(r'\d+<.*/keys>', args):
        # a K record names a job's output: the job that published it
        # must have exited (everything it wrote durable) before
        m2 = re.search(r' K [0-9a-f]{16} [0-9a-f]{16} \S+ ([^\\"]+)', args)
        if m2:
            keys += 1
            out = path(os.path.join(outs, m2.group(1)))
            w = renamer.get(out)
            if w is None:
                problems.append(f'a key for {out}, which no process renamed into place')
            elif w not in exited:
                problems.append(f'a key for {out} while its writer {prog.get(w)} {w} still ran')
for pid, p in pending.items():
    for d, what in p.items():
        problems.append(f'{prog.get(pid)} {pid}: {what}, then no fsync of {d}')
need = {'voxelize', 'svo-to-dag', 'symmetry-merge', 'encode', 'colorize',
        'render', 'lossy-cluster', 'edit', 'voxdag'}
missing = need - stages
print(f'renames {renames}')
print(f'keys {keys}')
print(f'stages {" ".join(sorted(stages & need))}')
if missing:
    print(f'MISSING {" ".join(sorted(missing))}')
for p in problems[:10]:
    print(f'PROBLEM {p}')
print(f'problems {len(problems)}')
PY
renames=$(sed -n 's/^renames //p' "$T/verdict")
if grep -q '^MISSING' "$T/verdict"; then
	fail every_stage_traced "$(grep '^MISSING' "$T/verdict")"
else
	pass every_stage_traced
fi
if [ "${renames:-0}" -lt 20 ]; then
	fail renames_seen "only ${renames:-0} renames traced"
elif grep -q '^PROBLEM' "$T/verdict" || ! grep -q '^problems 0$' "$T/verdict"; then
	fail fsync_rename_dirsync_order "$(grep '^problems' "$T/verdict")" "$(grep '^PROBLEM' "$T/verdict")"
else
	pass fsync_rename_dirsync_order
fi
[ -z "$(find "$D" -name '*.tmp.*')" ] && pass no_temporaries_left ||
	fail no_temporaries_left "$(find "$D" -name '*.tmp.*')"
echo "publish.sh: $renames renames and $(sed -n 's/^keys //p' "$T/verdict") keys checked" >&2
