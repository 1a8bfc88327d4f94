# fetch-common.sh - what the config/fetch-*.sh scripts share; sourced by
# them, not run. Set `me` (the script's name for messages), then
#
#   fetch_args HELP_LINES "$@"
#
# prints lines 2..HELP_LINES of the script's header for -h/--help (exit 0),
# rejects any other option or a second argument (usage, exit 2), and sets
# `cache` to the first argument, else $VOXDAG_DATA, else out/data.

die() {
	echo "$me: $*" >&2
	exit 1
}

fetch_usage() {
	echo "usage: $me [CACHE_DIR]" >&2
	exit 2
}

fetch_args() {
	help_lines=$1
	shift
	case "${1:-}" in
	-h | --help)
		sed -n "2,${help_lines}p" "$0" | sed 's/^# \{0,1\}//'
		exit 0
		;;
	-*) fetch_usage ;;
	esac
	[ $# -le 1 ] || fetch_usage
	cache=${1:-${VOXDAG_DATA:-out/data}}
}
