#!/usr/bin/env bash
# OpenVDB from the outside: voxelize GRID.vdb, vdb-export, and vdb_print
# (OpenVDB's own tool) agreeing on the active voxel count.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
V=$BIN/voxelize
X=$BIN/vdb-export
G="$T/grids"
mkdir -p "$G"
expect make_grids 0 '' $BIN/vdb-make-test-grids "$G"
help_lists_options help_matches_code_vdb_export vdb-export stages/vdb-export/main.c
help_lists_options help_matches_code_vdb_make_test_grids vdb-make-test-grids stages/vdb-make-test-grids/main.c

stat_of() { # stat_of FILE KEY: the number after "KEY": in a stats file
	sed -n "s/^ *\"$2\": \([0-9.e+-]*\),*$/\1/p" "$1" | head -n 1
}
active_of() { # active_of FILE.vdb: vdb_print's active voxel count
	vdb_print -l "$1" | sed -n 's/^ *Number of active voxels: *\([0-9,]*\)$/\1/p' | tr -d , | head -n 1
}
same() { # same NAME GOT WANT
	if [ -n "$2" ] && [ "$2" = "$3" ]; then pass "$1"; else fail "$1" "got '$2', want '$3'"; fi
}

# --- import: the counts OpenVDB reports
expect sphere_active 0 '' $V "$G/sphere.vdb" -o "$T/s" -q
same sphere_active_count "$(stat_of "$T/s/voxelize.stats.json" voxels)" "$(active_of "$G/sphere.vdb")"
expect sphere_chunks_check 0 '' $BIN/chunk-check "$T"/s/*.svo
grep -q '"mode": "active"' "$T/s/voxelize.stats.json" && grep -q '"grid": "sphere"' "$T/s/voxelize.stats.json" &&
	pass sphere_stats_name_mode || fail sphere_stats_name_mode "$(cat "$T/s/voxelize.stats.json")"
expect sphere_solid 0 '' $V "$G/sphere.vdb" -o "$T/solid" --vdb-mode levelset-solid -q
expect sphere_surface 0 '' $V "$G/sphere.vdb" -o "$T/surf" --vdb-mode levelset-surface --chunk-level 2 -q
solid=$(stat_of "$T/solid/voxelize.stats.json" voxels)
surf=$(stat_of "$T/surf/voxelize.stats.json" voxels)
# radius 20: 4/3 pi r^3 = 33510 inside; the shell is a few thousand
[ "$solid" -gt 32000 ] && [ "$solid" -lt 35000 ] && [ "$surf" -gt 3000 ] && [ "$surf" -lt "$solid" ] &&
	pass sphere_solid_surface_sizes || fail sphere_solid_surface_sizes "solid $solid surface $surf"
expect fog_tiles 0 '' $V "$G/fog.vdb" -o "$T/fog" --vdb-mode fog -q
same fog_tiles_count "$(stat_of "$T/fog/voxelize.stats.json" voxels)" "$(active_of "$G/fog.vdb")"
expect fog_threshold 0 '' $V "$G/fog.vdb" -o "$T/fog5" --vdb-mode fog --fog-threshold 0.5 -q
same fog_threshold_count "$(stat_of "$T/fog5/voxelize.stats.json" voxels)" \
	"$(( $(active_of "$G/fog.vdb") - 10 * 11 * 31 ))"
expect resample 0 '' $V "$G/fog.vdb" -o "$T/res" --levels 5 -q
same resample_levels "$(stat_of "$T/res/voxelize.stats.json" levels)" 5
same resample_factor "$(stat_of "$T/res/voxelize.stats.json" resample_factor)" 8
expect first_grid_default 0 '' $V "$G/two.vdb" -o "$T/a" -q
# the first by name ('a'), though 'b' is first in the file: OpenVDB's
# io::File lists a file's grids by name only
grep -q '"grid": "a"' "$T/a/voxelize.stats.json" && pass first_grid_is_first_by_name || fail first_grid_is_first_by_name "$(cat "$T/a/voxelize.stats.json")"
expect grid_by_name 0 '' $V "$G/two.vdb" -o "$T/b" --grid a -q
same grid_by_name_count "$(stat_of "$T/b/voxelize.stats.json" voxels)" 1000

# --- colours from a Vec3 grid beside the density grid (exact values:
# tests/unit/test_vdb.c, test_colour)
ls "$T"/s/*.col >/dev/null 2>&1 && fail no_colour_grid_no_col "$(ls "$T/s")" || pass no_colour_grid_no_col
C="$G/colour.vdb"
expect colour_default 0 "colours from grid 'Cd' \(vec3s, same transform" \
	$V "$C" --grid density -o "$T/col" --chunk-level 1
n_svo=$(ls "$T"/col/*.svo | wc -l)
n_col=$(ls "$T"/col/*.col | wc -l)
[ "$n_svo" -gt 1 ] && [ "$n_col" = "$n_svo" ] && pass colour_one_col_per_cell ||
	fail colour_one_col_per_cell "$n_svo svo, $n_col col"
expect colour_chunks_check 0 '' $BIN/chunk-check "$T"/col/*.col
grep -q '"colour_grid": "Cd"' "$T/col/voxelize.stats.json" && pass colour_stats_name ||
	fail colour_stats_name "$(cat "$T/col/voxelize.stats.json")"
expect colour_none 0 '' $V "$C" --grid density -o "$T/nocol" --chunk-level 1 --no-colours -q
ls "$T"/nocol/*.col >/dev/null 2>&1 && fail colour_none_no_col "$(ls "$T/nocol")" || pass colour_none_no_col
# the same cells and voxels (the bytes differ only in the arguments the
# chunks record)
same colour_same_cells "$(cd "$T/col" && ls *.svo)" "$(cd "$T/nocol" && ls *.svo)"
same colour_same_voxels "$(stat_of "$T/col/voxelize.stats.json" voxels)" \
	"$(stat_of "$T/nocol/voxelize.stats.json" voxels)"
expect colour_vec3i 0 "colours from grid 'rgb8' \(vec3i" $V "$C" --grid density -o "$T/c8" --colour-grid rgb8
expect colour_other_transform 0 "colours from grid 'Cd_coarse' .*other transform: nearest" \
	$V "$C" --grid density -o "$T/cc" --colour-grid Cd_coarse
expect colour_grid_and_no_colours 2 'contradict' $V "$C" -o "$T/bad" --colour-grid Cd --no-colours
expect colour_grid_on_mesh 2 'OpenVDB' $V tests/data/bunny.ply -o "$T/bad" --levels 5 --colour-grid Cd

# --- export, and OpenVDB reading it back
expect export 0 '^[0-9]+ voxels from' $X -o "$T/sphere-out.vdb" "$T/solid"
same export_vdb_print_count "$(active_of "$T/sphere-out.vdb")" "$solid"
expect round_trip 0 '' $V "$T/sphere-out.vdb" -o "$T/rt" -q
same round_trip_count "$(stat_of "$T/rt/voxelize.stats.json" voxels)" "$solid"
expect export_mesh_chunks 0 '' $V tests/data/bunny.ply -o "$T/bunny" --levels 7 --chunk-level 1 -q
expect export_mesh 0 '' $X -o "$T/bunny.vdb" --grid-name bunny "$T"/bunny/*.svo
same export_mesh_count "$(active_of "$T/bunny.vdb")" "$(stat_of "$T/bunny/voxelize.stats.json" voxels)"
expect export_no_inputs 2 'no CHUNK' $X -o "$T/x.vdb"
expect export_no_output 2 'output' $X "$T/solid"
head -c 100 "$(ls "$T"/solid/*.svo | head -n 1)" > "$T/cut.svo"
expect export_truncated_chunk 1 "truncated" $X -o "$T/x.vdb" "$T/cut.svo"
[ ! -e "$T/x.vdb" ] && pass export_failure_leaves_nothing || fail export_failure_leaves_nothing "$(ls "$T")"
expect export_mixed_grids 1 'different grids|mismatch' $X -o "$T/x.vdb" "$T/solid" "$T/bunny"

# --- bad input: exit 1, one line, the cause named, nothing left behind
bad() { bad_voxelize "$@"; } # bad NAME PATTERN FILE [ARGS...]
bad empty_grid 'no voxel' "$G/empty.vdb"
bad missing_grid "no grid named 'c'.*'a', 'b'" "$G/two.vdb" --grid c
cp tests/data/bunny.ply "$T/bunny.vdb"
bad not_vdb 'not an OpenVDB file' "$T/bunny.vdb"
head -c 5000 "$G/sphere.vdb" > "$T/cut.vdb"
bad truncated_vdb 'truncated' "$T/cut.vdb"
head -c 40 "$G/sphere.vdb" > "$T/cut_header.vdb"
bad truncated_vdb_header 'truncated' "$T/cut_header.vdb"
bad missing_vdb 'No such file' "$T/none.vdb"
bad rotated 'rotated transform' "$G/rotated.vdb"
bad nonuniform 'cubic voxels' "$G/nonuniform.vdb"
bad fog_as_level_set 'not a level set' "$G/fog.vdb" --vdb-mode levelset-solid
bad colour_grid_not_vec3 "colour grid 'color' holds float values; colours come from vec3s" \
	"$G/colour.vdb" --grid density --colour-grid color
bad colour_grid_missing "no grid named 'Cd_none'.*'Cd', 'Cd_coarse'" "$G/colour.vdb" --colour-grid Cd_none
expect bad_mode 2 'vdb-mode' $V "$G/sphere.vdb" -o "$T/bad" --vdb-mode smoke
expect bad_threshold 2 'fog-threshold' $V "$G/sphere.vdb" -o "$T/bad" --fog-threshold lots
expect vdb_option_on_mesh 2 'OpenVDB' $V tests/data/bunny.ply -o "$T/bad" --levels 5 --grid a
