#!/bin/sh
# fetch-sponza.sh - fetches the Sponza atrium that config/sponza-64k.yaml
# voxelizes: Marko Dabrovic's original model (2002; 66,454 triangles,
# geometry only), as a zip in a public GitHub repository, pinned by commit.
#
#   config/fetch-sponza.sh [CACHE_DIR]
#
# CACHE_DIR defaults to $VOXDAG_DATA, else out/data. Leaves the model at
# CACHE_DIR/sponza/sponza.obj with a SOURCE note beside it. Does nothing if
# it is already there. Needs curl (or SPONZA_ZIP=/path/to/sponza.zip, a copy
# already at hand), unzip and sha256sum. The zip's sha256 is checked.
#
# Which Sponza: the SSVDAG paper's scene is Crytek's 2010 remake (~262K
# triangles without the plants). Every public copy of that one we could
# reach keeps its mesh in a file too large for the snapshots we can fetch,
# so this is the original it remade: the same building, a coarser mesh;
# at 65536^3 it gives 27.6 G voxels, the remake 40.8 G (the paper's).
# Licence: the repository it comes from states none; the model has been
# given away by its author for free use since 2002 (say so if you publish
# figures made with it).
#
# Exit status: 0 success (or already present), 1 failure, 2 usage.

set -eu

URL=https://raw.githubusercontent.com/YangYuchu/cg/c16837cf16cc4afaafa920c609cd0291044ffb0a/sponza.zip
ZIP_SHA256=4633a31330f4ac8fb1e578e910949eb6b5b2cc18c8ec9b5a7befef6bef7a63be
OBJ_SHA256=5b4f8bc4f847aef7f0bd20bc3647f1d72843188c0a650d52ac8e0700c2e5f092

me=fetch-sponza.sh
. "$(dirname "$0")/fetch-common.sh"
fetch_args 21 "$@"
dest=$cache/sponza
model=$dest/sponza.obj

if [ -s "$model" ] && [ "$(sha256sum "$model" | cut -d' ' -f1)" = "$OBJ_SHA256" ]; then
	echo "$me: '$model' is already there"
	exit 0
fi

for tool in unzip sha256sum; do
	command -v "$tool" >/dev/null 2>&1 || die "'$tool' not found"
done
mkdir -p "$dest" || die "cannot create '$dest'"
tmp=$dest/.unpack.$$
rm -rf "$tmp"
mkdir -p "$tmp"
trap 'rm -rf "$tmp"' EXIT

if [ -n "${SPONZA_ZIP:-}" ]; then
	[ -f "$SPONZA_ZIP" ] && [ -r "$SPONZA_ZIP" ] ||
		die "cannot read '$SPONZA_ZIP' (SPONZA_ZIP)"
	cp "$SPONZA_ZIP" "$tmp/sponza.zip" || die "cannot copy '$SPONZA_ZIP'"
	from=$SPONZA_ZIP
else
	command -v curl >/dev/null 2>&1 ||
		die "'curl' not found (or set SPONZA_ZIP to a copy of $URL)"
	echo "$me: downloading $URL (1.3 MB)"
	curl -fsSL -o "$tmp/sponza.zip" "$URL" ||
		die "cannot download $URL (or set SPONZA_ZIP to a copy of it)"
	from=$URL
fi
sha=$(sha256sum "$tmp/sponza.zip" | cut -d' ' -f1)
[ "$sha" = "$ZIP_SHA256" ] ||
	die "the zip's sha256 is $sha, not $ZIP_SHA256: not the file this" \
	    "script was written for"
unzip -q -d "$tmp" "$tmp/sponza.zip" sponza.obj ||
	die "cannot unpack sponza.obj from the zip"
[ "$(sha256sum "$tmp/sponza.obj" | cut -d' ' -f1)" = "$OBJ_SHA256" ] ||
	die "sponza.obj in the zip is not the expected file"

cat >"$dest/SOURCE" <<EOF
Sponza atrium by Marko Dabrovic (2002), Max2Obj export, geometry only
from $from (sha256 $ZIP_SHA256)
repository github.com/YangYuchu/cg at c16837cf16cc4afaafa920c609cd0291044ffb0a; it states no licence
fetched by config/fetch-sponza.sh on $(date -u +%Y-%m-%dT%H:%M:%SZ)
EOF
# Renamed last, so an interrupted run never leaves a partial model behind.
mv "$tmp/sponza.obj" "$model.tmp"
mv "$model.tmp" "$model"
echo "$me: model at '$model' ($(wc -c <"$model") bytes, sha256 $OBJ_SHA256)"
exit 0
