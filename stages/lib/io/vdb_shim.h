// vdb_shim.h - what the OpenVDB shim's two files share (C++ only):
// vdb.cc reads grids (voxelize-vdb, the colour grids), vdb_write.cc writes
// them (vdb-export, the test grids). Two files because OpenVDB's templates
// make each a long compile: apart, they build side by side.
#ifndef VD_VDB_SHIM_H
#define VD_VDB_SHIM_H

#include "voxdag.h"

#include <openvdb/openvdb.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <mutex>
#include <string>
#include <vector>

namespace vd_shim {

inline void init_once()
{
	static std::once_flag once;
	std::call_once(once, [] { openvdb::initialize(); });
}

inline int fail_exception(const char *what, const std::exception &e)
{
	return vd_fail(VD_ERR_INTERNAL, "%s: OpenVDB: %s", what, e.what());
}

// Local voxel (x, y, z) of each of a brick's 64 bits.
struct brick_table {
	uint8_t x[64], y[64], z[64];
	brick_table()
	{
		for (int b = 0; b < 64; b++) {
			uint32_t X, Y, Z;
			vd_morton3_decode(uint64_t(b), &X, &Y, &Z);
			x[b] = uint8_t(X), y[b] = uint8_t(Y), z[b] = uint8_t(Z);
		}
	}
};

} // namespace vd_shim

#endif
