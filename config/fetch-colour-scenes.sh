#!/bin/sh
# fetch-colour-scenes.sh - fetches the three real textured scenes of the
# colour benchmarks (issue 11: tests/bench/colour_table.sh, Table 3 of
# Dolonius et al. 2017) from Debian packages, each with its textures.
#
#   config/fetch-colour-scenes.sh [CACHE_DIR]
#
# CACHE_DIR defaults to $VOXDAG_DATA, else out/data. Leaves each scene's
# package directory (model + textures, unchanged) at CACHE_DIR/<name>/, with
# the package's copyright file and a SOURCE note beside it; a scene already
# there is skipped. Needs apt-get, dpkg-deb, tar and sha256sum; no root.
# Downloads ~480 MB of .debs into CACHE_DIR/debs, deleted once unpacked.
#
# The scenes (Debian bookworm; every file's sha256 is checked, see below):
#   fg-cg57/CG-57.ac  USS Lake Champlain (CG-57) cruiser, high-detail
#       model: AC3D, 180k triangles, 6 PNG textures. flightgear-data-models
#       1:2020.3.16+dfsg-1, Models/Maritime/Military/CG-57-high-detail.
#       GPL-2+ (FlightGear; copyright file: Files: *).
#   fg-truman/truman.ac  USS Harry S. Truman (Nimitz-class carrier): AC3D,
#       19 PNG textures and one SGI .rgb (wake.rgb). Same package,
#       Models/Geometry/Nimitz (the directory also holds the Vinson and
#       deck-object models). GPL-2+.
#   torcs-brondehach/brondehach.acc  TORCS road track "Brondehach"
#       (scenery: track, terrain, trees, stands): TORCS's AC3D variant with
#       ~210 PNG textures (base unit used; schemas/colour-rule.md).
#       torcs-data 1.3.7+dfsg-5, tracks/road/brondehach. Free Art License
#       (copyright file: data/tracks/road/brondehach/*, J.-C. Durieu).
#       Chosen among TORCS's tracks because its kids counts are right: 22
#       of the 25 others declare more kids than they hold (voxelize reads
#       them to the end of the file, as TORCS does, with one warning).
#
# Exit status: 0 success (or already present), 1 failure, 2 usage.

set -eu
me=fetch-colour-scenes.sh

# name package version directory-in-package model tree-digest
# The digest is sha256 of `sha256sum` over the directory's files in
# C-locale path order (tree_digest below): any changed, missing or extra
# file changes it.
SCENES='
fg-cg57 flightgear-data-models 1:2020.3.16+dfsg-1 usr/share/games/flightgear/Models/Maritime/Military/CG-57-high-detail CG-57.ac b7421bddcc31fb3603e63b403c34df9136970062a4a54f9ea017e602d92cf18d
fg-truman flightgear-data-models 1:2020.3.16+dfsg-1 usr/share/games/flightgear/Models/Geometry/Nimitz truman.ac 17744b23120f48c912aa847d14c9f31d603a7614880add8c20172787e76161d0
torcs-brondehach torcs-data 1.3.7+dfsg-5 usr/share/games/torcs/tracks/road/brondehach brondehach.acc 067c5a02283d40ba08c4559307af83faa3097a9defddca43af6a793af3e124b7
'

. "$(dirname "$0")/fetch-common.sh"
fetch_args 12 "$@"
for tool in apt-get dpkg-deb tar sha256sum; do
	command -v "$tool" >/dev/null 2>&1 ||
		die "'$tool' not found; this needs a Debian-based system (apt, dpkg)"
done
mkdir -p "$cache/debs" || die "cannot create '$cache/debs'"
debs=$(cd "$cache/debs" && pwd)

tree_digest() {
	(cd "$1" && find . -type f ! -name SOURCE ! -name copyright |
		LC_ALL=C sort | xargs -d '\n' sha256sum) | sha256sum | cut -d' ' -f1
}

# fetch_deb PACKAGE VERSION: the .deb's path on stdout, downloaded once.
fetch_deb() {
	for f in "$debs/${1}_"*.deb; do
		if [ -f "$f" ] && dpkg-deb --info "$f" >/dev/null 2>&1 &&
		   [ "$(dpkg-deb --field "$f" Version)" = "$2" ]; then
			echo "$f"
			return 0
		fi
	done
	echo "$me: downloading $1 $2 into '$debs'" >&2
	rm -f "$debs/${1}_"*.deb
	# apt-get writes into the current directory; as root it warns that
	# the _apt user cannot write there, which is harmless.
	(cd "$debs" && apt-get download "$1=$2" >&2) ||
		die "'apt-get download $1=$2' failed; check the network, that" \
		    "Debian's 'main' component is in the apt sources (bookworm" \
		    "has this version), and run 'apt-get update'"
	for f in "$debs/${1}_"*.deb; do
		[ -f "$f" ] && { echo "$f"; return 0; }
	done
	die "apt-get download left no ${1}_*.deb in '$debs'"
}

failed=0
echo "$SCENES" | while read -r name pkg ver dir model digest; do
	[ -n "$name" ] || continue
	dest=$cache/$name
	if [ -s "$dest/$model" ] && [ "$(tree_digest "$dest")" = "$digest" ]; then
		echo "$me: '$dest' is already there"
		continue
	fi
	deb=$(fetch_deb "$pkg" "$ver") || exit 1
	echo "$me: unpacking $dir from $pkg $ver"
	tmp=$cache/.unpack-$name.$$
	rm -rf "$tmp"
	mkdir -p "$tmp"
	dpkg-deb --fsys-tarfile "$deb" |
		tar -x -C "$tmp" "./$dir" "./usr/share/doc/$pkg/copyright" ||
		die "cannot unpack $dir from '$deb'"
	got=$(tree_digest "$tmp/$dir")
	if [ "$got" != "$digest" ]; then
		rm -rf "$tmp"
		die "$name: the files of $dir differ from those this script" \
		    "was written against (tree sha256 $got, want $digest)"
	fi
	cp "$tmp/usr/share/doc/$pkg/copyright" "$tmp/$dir/copyright"
	cat >"$tmp/$dir/SOURCE" <<EOF
Debian package $pkg $ver, directory /$dir
model $model; tree sha256 $digest (config/fetch-colour-scenes.sh)
fetched on $(date -u +%Y-%m-%dT%H:%M:%SZ)
EOF
	# Moved into place last: an interrupted run leaves no partial scene.
	rm -rf "$dest"
	mv "$tmp/$dir" "$dest"
	rm -rf "$tmp"
	echo "$me: $name at '$dest/$model'"
done || failed=1
[ $failed = 0 ] || exit 1
rm -f "$debs"/*.deb
rmdir "$debs" 2>/dev/null || true
exit 0
