/* vdb_modes.c - the names of the OpenVDB import modes, apart from vdb.cc
 * so that programs which only name modes (the runner, voxelize checking
 * its options) do not link OpenVDB and its ~30 MB of start-up memory. */
#include "voxdag.h"

#include <string.h>

const char *vd_vdb_mode_name(int mode)
{
	static const char *const names[] = {"active", "levelset-surface",
					    "levelset-solid", "fog"};
	return mode >= 0 && mode < VD_VDB_MODE_COUNT_ ? names[mode] : NULL;
}

int vd_vdb_mode_parse(const char *name, int *mode)
{
	for (int m = 0; m < VD_VDB_MODE_COUNT_; m++)
		if (strcmp(name, vd_vdb_mode_name(m)) == 0) {
			*mode = m;
			return VD_OK;
		}
	return vd_fail(VD_ERR_ARG, "unknown mode '%s' (active, levelset-surface, "
		       "levelset-solid, fog)", name);
}
