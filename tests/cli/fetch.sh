#!/usr/bin/env bash
# The config/fetch-*.sh scripts without the network: --help, usage errors,
# and fetch-sponza.sh refusing a zip that is not the pinned one (one line,
# exit 1, no model left behind).
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

for s in fetch-boeing fetch-colour-scenes fetch-sponza; do
	expect "${s}_help" 0 "^$s\.sh - fetches" sh "config/$s.sh" --help
	expect "${s}_bad_option" 2 "usage: $s\.sh \[CACHE_DIR\]" sh "config/$s.sh" -x
	expect "${s}_two_dirs" 2 "usage: $s\.sh \[CACHE_DIR\]" sh "config/$s.sh" "$T/a" "$T/b"
done

# Not a zip at all, then a zip holding a sponza.obj that is not the model.
echo "not a zip" > "$T/junk.zip"
SPONZA_ZIP=$T/junk.zip expect sponza_wrong_zip 1 "sha256 is [0-9a-f]{64}, not 4633a313" \
	sh config/fetch-sponza.sh "$T/cache"
mkdir -p "$T/fake" && printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > "$T/fake/sponza.obj"
(cd "$T/fake" && python3 -c 'import zipfile; zipfile.ZipFile("fake.zip", "w").write("sponza.obj")')
SPONZA_ZIP=$T/fake/fake.zip expect sponza_other_zip 1 "not 4633a313" \
	sh config/fetch-sponza.sh "$T/cache"
SPONZA_ZIP=$T/missing.zip expect sponza_missing_zip 1 "cannot read" \
	sh config/fetch-sponza.sh "$T/cache"
if [ -z "$(ls -A "$T/cache/sponza" 2>/dev/null)" ]; then
	pass sponza_nothing_left
else
	fail sponza_nothing_left "left in $T/cache/sponza:" "$(ls -A "$T/cache/sponza")"
fi
