#!/bin/sh
# fetch-boeing.sh - fetches the Boeing 777 model that config/boeing.yaml
# voxelizes, from Debian's flightgear-data-ai package (GPL-2+, FlightGear's
# AI aircraft, all AC3D).
#
#   config/fetch-boeing.sh [CACHE_DIR]
#
# CACHE_DIR defaults to $VOXDAG_DATA, else out/data. Leaves the model at
# CACHE_DIR/boeing777/77L.ac with the package's copyright file and a SOURCE
# note beside it. Does nothing if the model is already there. Needs apt-get
# (with Debian's main component in the sources), dpkg-deb and tar; no root:
# `apt-get download` fetches the .deb (~290 MB) into the cache, which is
# deleted once the model is out.
#
# Which model: AI/Aircraft/777/Models holds three airframes, one level of
# detail each, every one the whole aircraft plus its gear as a second object:
# 77F (777 Freighter), 77L (777-200LR) and 77W (777-300ER). 77F and 77L are
# the same geometry; 77W is the stretched fuselage (18 more surfaces, the
# same 6830 triangles). We take 77L: it is the 63.7 m long, 64.8 m span
# aircraft boeing.yaml's sizes are for, FlightGear's own default 777
# (777-fallback.xml points at it), and no less detailed than the others.
#
# Exit status: 0 success (or already present), 1 failure, 2 usage.

set -eu

PACKAGE=flightgear-data-ai
MEMBER=./usr/share/games/flightgear/AI/Aircraft/777/Models/77L.ac
COPYRIGHT=./usr/share/doc/$PACKAGE/copyright
# The file this script was written against (Debian bookworm,
# 1:2020.3.16+dfsg-1); another release may differ, which is only a note.
KNOWN_SHA256=b7b93a1133e2d91e5e35202480706094860d8fa52f261dc8cceba95a5a087faf

me=fetch-boeing.sh
. "$(dirname "$0")/fetch-common.sh"
fetch_args 13 "$@"
dest=$cache/boeing777
model=$dest/77L.ac

if [ -s "$model" ] && head -c 4 "$model" | grep -q '^AC3D'; then
	echo "$me: '$model' is already there"
	exit 0
fi

for tool in apt-get dpkg-deb tar sha256sum; do
	command -v "$tool" >/dev/null 2>&1 ||
		die "'$tool' not found; this needs a Debian-based system (apt, dpkg)"
done

mkdir -p "$dest" "$cache/debs" || die "cannot create '$dest'"
debs=$(cd "$cache/debs" && pwd)

# A .deb left by an interrupted run is reused only if dpkg-deb can read it.
deb=
for f in "$debs/${PACKAGE}_"*.deb; do
	[ -f "$f" ] && dpkg-deb --info "$f" >/dev/null 2>&1 && deb=$f
done
if [ -z "$deb" ]; then
	echo "$me: downloading $PACKAGE (about 290 MB) into '$debs'"
	rm -f "$debs/${PACKAGE}_"*.deb
	# apt-get writes into the current directory. As root it warns that
	# the _apt user cannot write there; harmless.
	if ! (cd "$debs" && apt-get download "$PACKAGE"); then
		die "'apt-get download $PACKAGE' failed; check the network, that" \
		    "Debian's 'main' component is in the apt sources, and run" \
		    "'sudo apt-get update' if the package lists are empty"
	fi
	for f in "$debs/${PACKAGE}_"*.deb; do
		[ -f "$f" ] && deb=$f
	done
	[ -n "$deb" ] || die "apt-get download left no ${PACKAGE}_*.deb in '$debs'"
fi
version=$(dpkg-deb --field "$deb" Version) ||
	die "cannot read '$deb' (a damaged download? delete it and rerun)"

echo "$me: unpacking ${MEMBER#./} from $PACKAGE $version"
tmp=$dest/.unpack.$$
rm -rf "$tmp"
mkdir -p "$tmp"
trap 'rm -rf "$tmp"' EXIT
dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$tmp" "$MEMBER" "$COPYRIGHT" ||
	die "cannot unpack $MEMBER from '$deb'; has the package layout changed?" \
	    "(list it with: dpkg-deb -c '$deb' | grep 777)"
head -c 4 "$tmp/$MEMBER" | grep -q '^AC3D' ||
	die "$MEMBER in '$deb' is not an AC3D file"

sha=$(sha256sum "$tmp/$MEMBER" | cut -d' ' -f1)
cp "$tmp/$COPYRIGHT" "$dest/copyright"
cat >"$dest/SOURCE" <<EOF
Debian package $PACKAGE $version, file ${MEMBER#.}
sha256 $sha
fetched by config/fetch-boeing.sh on $(date -u +%Y-%m-%dT%H:%M:%SZ)
EOF
# Renamed last, so an interrupted run never leaves a partial model behind.
mv "$tmp/$MEMBER" "$model.tmp"
mv "$model.tmp" "$model"
rm -f "$deb"
rmdir "$debs" 2>/dev/null || true

echo "$me: model at '$model' ($(wc -c <"$model") bytes, sha256 $sha)"
[ "$sha" = "$KNOWN_SHA256" ] ||
	echo "$me: note: this is not the file the script was written against" \
	     "(bookworm's); triangle counts in tests may differ"
exit 0
