#!/usr/bin/env bash
# Durable publishing seen from the system calls: a small pipeline (every
# stage of the default one: voxelize, svo-to-dag cells and merge,
# symmetry-merge, encode, render, the report) runs under strace, one log
# per thread, and every successful rename (file or directory, rename or
# renameat2) must be
#   - of a file fsynced before it by the same thread (or a staged
#     "<final>.tmp.<pid>.new" that thread published before, itself checked,
#     or a directory, whose files were each published inside it), and
#   - followed by an fsync of the directory holding the new name, with
#     nothing but renames and directory fsyncs in between.
# Skips (one line) where strace or python3 is missing.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
if ! command -v strace >/dev/null || ! command -v python3 >/dev/null; then
	echo "SKIP publish: needs strace and python3"
	exit 0
fi
if ! strace -f -o /dev/null true 2>/dev/null; then
	echo "SKIP publish: strace cannot trace here (ptrace not permitted)"
	exit 0
fi
sed -e "s|^name: default|name: publish|" -e "s|^levels: 9|levels: 7|" \
	-e "s|^resolutions: .*|resolutions: [7, 6]|" \
	-e "s|tests/data/bunny.ply|$PWD/tests/data/bunny.ply|" \
	config/default.yaml > "$T/p.yaml"
printf 'outputs: %s\n' "$T/out" >> "$T/p.yaml"
mkdir -p "$T/trace"
VOXDAG=$(cd "$BIN" && pwd)/voxdag
if ! (cd "$T" && strace -ff -y -qq -o "$T/trace/t" \
	-e trace=fsync,fdatasync,rename,renameat,renameat2 \
	"$VOXDAG" run p.yaml) > "$T/run.log" 2>&1; then
	fail pipeline_under_strace "$(tail -5 "$T/run.log")"
	exit 0
fi
pass pipeline_under_strace

python3 - "$T" "$T/trace" > "$T/verdict" 2>&1 <<'PY'
import os, re, sys
cwd, tdir = sys.argv[1], sys.argv[2]
ev_re = re.compile(r'^(fsync|fdatasync)\(\d+<(.*)>\)\s+=\s+0$|'
                   r'^(rename|renameat|renameat2)\((.*)\)\s+=\s+0$')
str_re = re.compile(r'"((?:[^"\\]|\\.)*)"')
def absp(p):
    return os.path.normpath(p if p.startswith('/') else os.path.join(cwd, p))
renames = files = dirs = 0
bad = []
for name in sorted(os.listdir(tdir)):
    ev = []
    for line in open(os.path.join(tdir, name)):
        m = ev_re.match(line.strip())
        if not m:
            continue
        if m.group(1):
            ev.append(('sync', os.path.normpath(m.group(2))))
        else:
            a, b = str_re.findall(m.group(4))[:2]
            ev.append(('rename', absp(a), absp(b), 'EXCHANGE' in m.group(4)))
    published = set()
    for i, e in enumerate(ev):
        if e[0] != 'rename':
            continue
        renames += 1
        src, dst, exch = e[1], e[2], e[3]
        is_dir = exch or os.path.isdir(dst)
        if not is_dir:
            files += 1
            if not any(x[0] == 'sync' and x[1] == src for x in ev[:i]) \
               and src not in published:
                bad.append('%s: rename %s -> %s without fsync of the file '
                           'before it' % (name, src, dst))
        else:
            dirs += 1
        published.add(dst)
        parent = os.path.dirname(dst)
        ok = False
        for x in ev[i + 1:]:
            if x[0] == 'sync' and x[1] == parent:
                ok = True
                break
            if x[0] == 'sync' and not os.path.isdir(x[1]):
                break  # a file of another publish started
        if not ok:
            bad.append('%s: rename %s -> %s not followed by fsync of %s'
                       % (name, src, dst, parent))
print('renames %d (files %d, directories %d)' % (renames, files, dirs))
for b in bad[:20]:
    print('BAD', b)
sys.exit(1 if bad or not renames else 0)
PY
rc=$?
if [ $rc -eq 0 ]; then
	pass fsync_rename_dirsync_order
else
	fail fsync_rename_dirsync_order "$(head -c 3000 "$T/verdict")"
fi
n=$(sed -n 's/^renames \([0-9]*\).*/\1/p' "$T/verdict")
[ "${n:-0}" -ge 20 ] && pass renames_seen ||
	fail renames_seen "only ${n:-0} renames traced"
[ -z "$(find "$T/out" -name '*.tmp.*')" ] && pass no_temporaries_left ||
	fail no_temporaries_left "$(find "$T/out" -name '*.tmp.*')"
