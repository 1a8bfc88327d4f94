// vdb.cc - the library's reading of OpenVDB files, behind the C interface
// of vd_vdb.h (vdb_write.cc writes them). Every entry point
// catches every exception and returns an error code with a detail line:
// nothing thrown crosses into C.
//
// Import reads one grid into memory (OpenVDB's sparse tree, loaded eagerly
// so a damaged file fails at open, not in a worker thread later) and hands
// out selected voxels per 8^3 block: a leaf's mask, or a whole tile. The
// C side (vdb_import.c) does the placement, chunking and writing.
#include "io/vdb_shim.h"
#include "io/vdb_test_grids.h"

using openvdb::Coord;
using openvdb::CoordBBox;
using vd_shim::brick_table; // the colour bricks
using vd_shim::fail_exception;
using vd_shim::init_once;

namespace {

// The grid types import reads. Level set and fog modes need a
// floating-point value; the others are read in `active` mode only.
enum value_kind { K_FLOAT, K_DOUBLE, K_BOOL, K_MASK, K_INT32, K_VEC3S, K_OTHER };

value_kind kind_of(const openvdb::GridBase &g)
{
	if (g.isType<openvdb::FloatGrid>()) return K_FLOAT;
	if (g.isType<openvdb::DoubleGrid>()) return K_DOUBLE;
	if (g.isType<openvdb::BoolGrid>()) return K_BOOL;
	if (g.isType<openvdb::MaskGrid>()) return K_MASK;
	if (g.isType<openvdb::Int32Grid>()) return K_INT32;
	if (g.isType<openvdb::Vec3SGrid>()) return K_VEC3S;
	return K_OTHER;
}

// Calls op(grid) with the grid cast to its concrete type.
template <typename Op> void dispatch(const openvdb::GridBase &g, Op &&op)
{
	switch (kind_of(g)) {
	case K_FLOAT: op(static_cast<const openvdb::FloatGrid &>(g)); break;
	case K_DOUBLE: op(static_cast<const openvdb::DoubleGrid &>(g)); break;
	case K_BOOL: op(static_cast<const openvdb::BoolGrid &>(g)); break;
	case K_MASK: op(static_cast<const openvdb::MaskGrid &>(g)); break;
	case K_INT32: op(static_cast<const openvdb::Int32Grid &>(g)); break;
	case K_VEC3S: op(static_cast<const openvdb::Vec3SGrid &>(g)); break;
	case K_OTHER: break;
	}
}

// The mode's tests on one value; only floating-point values have a sign.
template <typename T> bool inside(const T &v)
{
	if constexpr (std::is_floating_point_v<T>)
		return v <= T(0);
	else
		return false;
}
template <typename T> bool above(const T &v, double threshold)
{
	if constexpr (std::is_floating_point_v<T>)
		return double(v) > threshold;
	else
		return false;
}

// Does a voxel or tile of value v and activity `on` count, for the modes
// that decide per value (all but the surface, which also needs the
// neighbours)?
template <typename T> bool selected(int mode, double thr, const T &v, bool on)
{
	switch (mode) {
	case VD_VDB_ACTIVE: return on;
	case VD_VDB_FOG: return on && above(v, thr);
	case VD_VDB_LEVELSET_SOLID:
	case VD_VDB_LEVELSET_SURFACE: return inside(v);
	}
	return false;
}

// Bits of the 512-bit block masks (word x, bit 8y + z) at a face.
constexpr uint64_t Z0 = 0x0101010101010101ULL;  // z == 0
constexpr uint64_t Z7 = Z0 << 7;                // z == 7
constexpr uint64_t Y0 = 0xffULL;                // y == 0
constexpr uint64_t Y7 = Y0 << 56;               // y == 7

// The selected voxels of the 8^3 block at `o` (a multiple of 8): a leaf if
// the tree has one there, else the constant value of the tile or
// background covering it.
template <typename GridT, typename AccT>
void block_mask(AccT &acc, int mode, double thr, const Coord &o,
		uint64_t mask[8])
{
	using ValueT = typename GridT::ValueType;
	const auto *leaf = acc.probeConstLeaf(o);
	uint64_t solid[8];
	if (leaf) {
		if (mode == VD_VDB_ACTIVE) {
			for (int x = 0; x < 8; x++)
				mask[x] = leaf->getValueMask().template getWord<uint64_t>(x);
			return;
		}
		if (mode == VD_VDB_FOG) {
			for (int x = 0; x < 8; x++)
				mask[x] = 0;
			for (auto it = leaf->cbeginValueOn(); it; ++it)
				if (above(*it, thr)) {
					openvdb::Index i = it.pos();
					mask[i >> 6] |= 1ULL << (i & 63);
				}
			return;
		}
		for (int x = 0; x < 8; x++) {
			uint64_t w = 0;
			for (int b = 0; b < 64; b++)
				if (inside(leaf->getValue(openvdb::Index(x * 64 + b))))
					w |= 1ULL << b;
			solid[x] = w;
		}
	} else {
		ValueT v = acc.getValue(o);
		bool on = acc.isValueOn(o);
		uint64_t all = selected(mode, thr, v, on) ? ~0ULL : 0;
		for (int x = 0; x < 8; x++)
			solid[x] = mask[x] = all;
		if (mode != VD_VDB_LEVELSET_SURFACE)
			return;
	}
	if (mode == VD_VDB_LEVELSET_SOLID) {
		std::memcpy(mask, solid, sizeof solid);
		return;
	}
	// Surface: solid voxels with an outside face neighbour. Inside the
	// block by shifts of the outside mask; across its faces from the
	// neighbours' values (the accessor's cache keeps those reads cheap).
	uint64_t out[8];
	for (int x = 0; x < 8; x++)
		out[x] = ~solid[x];
	auto pos = [&](int x, int y, int z) {
		return !inside(acc.getValue(o.offsetBy(x, y, z)));
	};
	uint64_t fxm = 0, fxp = 0; // -x, +x faces: bit 8y + z
	for (int y = 0; y < 8; y++)
		for (int z = 0; z < 8; z++) {
			if (pos(-1, y, z)) fxm |= 1ULL << (8 * y + z);
			if (pos(8, y, z)) fxp |= 1ULL << (8 * y + z);
		}
	for (int x = 0; x < 8; x++) {
		uint64_t fym = 0, fyp = 0, fzm = 0, fzp = 0;
		for (int i = 0; i < 8; i++) {
			if (pos(x, -1, i)) fym |= 1ULL << i;       // y == 0 row
			if (pos(x, 8, i)) fyp |= 1ULL << (56 + i);
			if (pos(x, i, -1)) fzm |= 1ULL << (8 * i);  // z == 0 column
			if (pos(x, i, 8)) fzp |= 1ULL << (8 * i + 7);
		}
		uint64_t n = 0;
		n |= (out[x] << 1 & ~Z0) | fzm;  // neighbour z - 1
		n |= (out[x] >> 1 & ~Z7) | fzp;  // z + 1
		n |= (out[x] << 8 & ~Y0) | fym;  // y - 1
		n |= (out[x] >> 8 & ~Y7) | fyp;  // y + 1
		n |= x > 0 ? out[x - 1] : fxm;
		n |= x < 7 ? out[x + 1] : fxp;
		mask[x] = solid[x] & n;
	}
}

template <typename GridT>
using ConstAcc = openvdb::tree::ValueAccessor<const typename GridT::TreeType, false>;

// Reports every leaf with a selected voxel and every selected tile. In
// surface mode a tile is never wholly selected: only its shell of 8^3
// blocks can be, and only where a face meets an outside neighbour, so
// those blocks are reported as leaf-like masks.
template <typename GridT>
int scan_grid(const GridT &grid, int mode, double thr,
	      int (*fn)(void *, const vd_vdb_node *), void *ctx)
{
	const auto &tree = grid.tree();
	ConstAcc<GridT> acc(tree);
	vd_vdb_node n;
	// the selected voxels of the 8^3 block at o, passed on if there are any
	auto emit_block = [&](const Coord &o) -> int {
		block_mask<GridT>(acc, mode, thr, o, n.mask);
		uint64_t any = 0;
		for (int x = 0; x < 8; x++)
			any |= n.mask[x];
		if (!any)
			return VD_OK;
		n.origin[0] = o.x(), n.origin[1] = o.y(), n.origin[2] = o.z();
		n.dim = 8;
		n.is_leaf = 1;
		return fn(ctx, &n);
	};
	for (auto it = tree.cbeginLeaf(); it; ++it)
		if (int err = emit_block(it->origin()))
			return err;
	auto tiles = tree.cbeginValueAll();
	tiles.setMaxDepth(tiles.getLeafDepth() - 1); // tiles only, no voxels
	for (; tiles; ++tiles) {
		CoordBBox bb;
		tiles.getBoundingBox(bb);
		if (mode != VD_VDB_LEVELSET_SURFACE) {
			if (!selected(mode, thr, *tiles, tiles.isValueOn()))
				continue;
			n.origin[0] = bb.min().x(), n.origin[1] = bb.min().y(),
			n.origin[2] = bb.min().z();
			n.dim = uint32_t(bb.dim().x());
			n.is_leaf = 0;
			if (int err = fn(ctx, &n))
				return err;
			continue;
		}
		if (!inside(*tiles))
			continue;
		const int nb = bb.dim().x() / 8;
		for (int bx = 0; bx < nb; bx++)
			for (int by = 0; by < nb; by++)
				for (int bz = 0; bz < nb; bz++) {
					int b[3] = {bx, by, bz};
					bool shell = false, check = false;
					for (int a = 0; a < 3; a++)
						for (int s = 0; s < 2; s++) {
							if (b[a] != (s ? nb - 1 : 0))
								continue;
							shell = true;
							// the 8^3 block across this face
							Coord q = bb.min().offsetBy(8 * bx, 8 * by, 8 * bz);
							q[a] += s ? 8 : -8;
							if (acc.probeConstLeaf(q) || !inside(acc.getValue(q)))
								check = true;
						}
					if (!shell) // interior: skip to the far face
						bz = nb - 2 > bz ? nb - 2 : bz;
					if (!check)
						continue;
					if (int err = emit_block(bb.min().offsetBy(
						    8 * bx, 8 * by, 8 * bz)))
						return err;
				}
	}
	return VD_OK;
}
} // namespace

struct vd_vdb {
	openvdb::GridBase::ConstPtr grid;
	int mode;
	double thr;
};

namespace {

// Reads the chosen grid; the caller catches.
int read_grid(const char *path, const char *name, openvdb::GridBase::Ptr *out)
{
	init_once();
	FILE *f = std::fopen(path, "rb");
	if (!f)
		return vd_fail(VD_ERR_IO, "%s", std::strerror(errno));
	uint64_t grids = 0;
	int err = vd_vdb_walk(f, &grids);
	std::fclose(f);
	if (err)
		return err;
	if (grids == 0)
		return vd_fail(VD_ERR_EMPTY, "the file holds no grid");
	openvdb::io::File file(path);
	try {
		file.open(false); // no delayed loading: damage shows here
		std::vector<std::string> names;
		for (auto it = file.beginName(); it != file.endName(); ++it)
			names.push_back(it.gridName());
		if (names.empty()) {
			file.close();
			return vd_fail(VD_ERR_EMPTY, "the file holds no grid");
		}
		std::string want_name = name ? name : names[0];
		bool found = false;
		for (auto &n : names)
			found |= n == want_name;
		if (!found) {
			std::string list;
			for (auto &n : names)
				list += (list.empty() ? "'" : ", '") + n + "'";
			file.close();
			return vd_fail(VD_ERR_ARG, "no grid named '%s' (grids: %s)",
				       want_name.c_str(), list.c_str());
		}
		*out = file.readGrid(want_name);
		file.close();
	} catch (const std::exception &e) {
		return vd_fail(VD_ERR_TRUNCATED, "cut short or damaged: %s", e.what());
	}
	return VD_OK;
}

// voxdag grids are axis-aligned cubes: refuse what is not a uniform scale
// plus translation rather than resample silently.
int check_transform(const openvdb::GridBase &g, double *voxel_size,
		    double translation[3])
{
	const openvdb::math::Transform &xf = g.transform();
	if (!xf.isLinear())
		return vd_fail(VD_ERR_UNSUPPORTED, "grid '%s' has a non-linear "
			       "(frustum) transform; voxdag needs axis-aligned "
			       "cubic voxels: resample it first (OpenVDB "
			       "tools::resampleToMatch)", g.getName().c_str());
	openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
	double s = m(0, 0);
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			if (i != j && std::fabs(m(i, j)) > 1e-9 * std::fabs(s))
				return vd_fail(VD_ERR_UNSUPPORTED, "grid '%s' has a "
					       "rotated transform; voxdag needs "
					       "axis-aligned cubic voxels: "
					       "resample it first (OpenVDB "
					       "tools::resampleToMatch)",
					       g.getName().c_str());
	if (!(s > 0) || std::fabs(m(1, 1) - s) > 1e-9 * s ||
	    std::fabs(m(2, 2) - s) > 1e-9 * s)
		return vd_fail(VD_ERR_UNSUPPORTED, "grid '%s' has voxels of %g x "
			       "%g x %g; voxdag needs cubic voxels of positive "
			       "size: resample it first (OpenVDB "
			       "tools::resampleToMatch)", g.getName().c_str(),
			       m(0, 0), m(1, 1), m(2, 2));
	openvdb::Vec3d t = m.getTranslation();
	*voxel_size = s;
	for (int a = 0; a < 3; a++)
		translation[a] = t[a];
	return VD_OK;
}

int check_mode(const openvdb::GridBase &g, int mode)
{
	value_kind k = kind_of(g);
	if (mode < 0 || mode >= VD_VDB_MODE_COUNT_)
		return vd_fail(VD_ERR_ARG, "mode %d", mode);
	if (k == K_OTHER)
		return vd_fail(VD_ERR_UNSUPPORTED, "grid '%s' holds %s values; "
			       "voxdag reads float, double, bool, mask, int32 "
			       "and vec3s grids", g.getName().c_str(),
			       g.valueType().c_str());
	if (mode != VD_VDB_ACTIVE && k != K_FLOAT && k != K_DOUBLE)
		return vd_fail(VD_ERR_UNSUPPORTED, "mode %s needs a float or "
			       "double grid; '%s' holds %s values (use --vdb-mode "
			       "active)", vd_vdb_mode_name(mode),
			       g.getName().c_str(), g.valueType().c_str());
	if (mode == VD_VDB_LEVELSET_SOLID || mode == VD_VDB_LEVELSET_SURFACE) {
		double bg = 0;
		dispatch(g, [&](const auto &grid) {
			using T = typename std::decay_t<decltype(grid)>::ValueType;
			if constexpr (std::is_floating_point_v<T>)
				bg = double(grid.background());
		});
		if (!(bg > 0))
			return vd_fail(VD_ERR_UNSUPPORTED, "grid '%s' has "
				       "background %g, so everything far away "
				       "would be inside: not a level set (try "
				       "--vdb-mode fog or active)",
				       g.getName().c_str(), bg);
	}
	return VD_OK;
}

} // namespace

extern "C" int vd_vdb_open(struct vd_vdb **out, const char *path,
			   const struct vd_vdb_select *sel,
			   struct vd_vdb_info *info)
{
	*out = nullptr;
	try {
		openvdb::GridBase::Ptr grid;
		int err = read_grid(path, sel->grid_name, &grid);
		if (err)
			return err;
		double vs = 0, tr[3] = {0, 0, 0};
		if ((err = check_transform(*grid, &vs, tr)) ||
		    (err = check_mode(*grid, sel->mode)))
			return err;
		if (info) {
			std::memset(info, 0, sizeof *info);
			std::snprintf(info->grid_name, sizeof info->grid_name, "%s",
				      grid->getName().c_str());
			std::snprintf(info->value_type, sizeof info->value_type,
				      "%s", grid->valueType().c_str());
			std::snprintf(info->grid_class, sizeof info->grid_class,
				      "%s", openvdb::GridBase::gridClassToString(
						    grid->getGridClass()).c_str());
			info->voxel_size = vs;
			for (int a = 0; a < 3; a++)
				info->translation[a] = tr[a];
			info->active_voxels = grid->activeVoxelCount();
			info->leaves = grid->baseTree().leafCount();
			CoordBBox bb = grid->evalActiveVoxelBoundingBox();
			info->has_active = !bb.empty();
			for (int a = 0; a < 3 && info->has_active; a++) {
				info->active_min[a] = bb.min()[a];
				info->active_max[a] = bb.max()[a];
			}
		}
		auto *v = new vd_vdb;
		v->grid = grid;
		v->mode = sel->mode;
		v->thr = sel->fog_threshold;
		*out = v;
		return VD_OK;
	} catch (const std::bad_alloc &) {
		return vd_fail(VD_ERR_NOMEM, "reading the grid");
	} catch (const std::exception &e) {
		return fail_exception("open", e);
	}
}

extern "C" void vd_vdb_close(struct vd_vdb *v)
{
	delete v;
}

extern "C" int vd_vdb_scan(struct vd_vdb *v,
			   int (*fn)(void *ctx, const struct vd_vdb_node *n),
			   void *ctx)
{
	try {
		int err = VD_OK;
		dispatch(*v->grid, [&](const auto &grid) {
			using G = std::decay_t<decltype(grid)>;
			err = scan_grid<G>(grid, v->mode, v->thr, fn, ctx);
		});
		return err;
	} catch (const std::bad_alloc &) {
		return vd_fail(VD_ERR_NOMEM, "scanning the grid");
	} catch (const std::exception &e) {
		return fail_exception("scan", e);
	}
}

extern "C" int vd_vdb_leaf_mask(struct vd_vdb *v, const int32_t origin[3],
				uint64_t mask[8])
{
	try {
		dispatch(*v->grid, [&](const auto &grid) {
			using G = std::decay_t<decltype(grid)>;
			ConstAcc<G> acc(grid.tree());
			block_mask<G>(acc, v->mode, v->thr,
				      Coord(origin[0], origin[1], origin[2]), mask);
		});
		return VD_OK;
	} catch (const std::exception &e) {
		return fail_exception("leaf", e);
	}
}

// ------------------------------------------------------------------ colour

struct vd_vdb_colour {
	openvdb::GridBase::ConstPtr grid;
	openvdb::math::Transform::ConstPtr density_xf;
	bool same;
};

namespace {

enum colour_kind { C_VEC3S, C_VEC3D, C_VEC3I, C_NONE };

colour_kind colour_kind_of(const openvdb::GridBase &g)
{
	if (g.isType<openvdb::Vec3SGrid>()) return C_VEC3S;
	if (g.isType<openvdb::Vec3DGrid>()) return C_VEC3D;
	if (g.isType<openvdb::Vec3IGrid>()) return C_VEC3I;
	return C_NONE;
}

// The names a colour grid goes by when none is given: Houdini's Cd, then
// the spellings other exporters use.
const char *const colour_names[] = {"Cd", "color", "colour", "rgb"};

// The first of those names (in that order, as OpenVDB lists a file's
// grids by name, not in the order they were written) that a grid with
// Vec3 values has; "" when none. The caller catches.
int find_colour_grid(const char *path, std::string *name)
{
	name->clear();
	openvdb::io::File file(path);
	try {
		file.open(false);
		openvdb::GridPtrVecPtr grids = file.readAllGridMetadata();
		file.close();
		for (const char *n : colour_names)
			for (const auto &g : *grids)
				if (g->getName() == n &&
				    colour_kind_of(*g) != C_NONE) {
					*name = n;
					return VD_OK;
				}
	} catch (const std::exception &e) {
		return vd_fail(VD_ERR_TRUNCATED, "cut short or damaged: %s", e.what());
	}
	return VD_OK;
}

// Colour values as sRGB bytes: floats in 0..1 scaled by 255, ints as they
// are; rounded half up, clamped; NaN is 0 (as PLY float colours).
uint8_t colour_byte(double v)
{
	double d = v * 255.0;
	if (!(d > 0))
		return 0;
	return d >= 255 ? 255 : uint8_t(d + 0.5);
}
uint8_t colour_byte(int32_t v)
{
	return v <= 0 ? 0 : v >= 255 ? 255 : uint8_t(v);
}

int32_t round_index(double x)
{
	double r = std::floor(x + 0.5); // nearest, halves up
	if (!(r > double(INT32_MIN)))
		return INT32_MIN;
	return r >= double(INT32_MAX) ? INT32_MAX : int32_t(r);
}

template <typename GridT>
void colour_bricks(const GridT &grid, const vd_vdb_colour &c,
		   const int32_t off[3], int shift, const uint64_t *keys,
		   const uint64_t *masks, size_t stride, size_t n, uint8_t *rgb)
{
	static const brick_table tab;
	using V = typename GridT::ValueType;
	using E = typename V::value_type;
	ConstAcc<GridT> acc(grid.tree());
	const V bg = grid.background();
	const openvdb::math::Transform &cxf = grid.transform();
	// the voxel nearest to the centre of ours, in the density's index
	// space: off + v 2^shift + (2^shift - 1)/2, halves up
	const int64_t half = shift ? int64_t(1) << (shift - 1) : 0;
	const double centre = (double(int64_t(1) << shift) - 1) / 2;
	for (size_t i = 0; i < n; i++) {
		uint32_t bx, by, bz;
		vd_morton3_decode(keys[i * stride], &bx, &by, &bz);
		const int64_t base[3] = {int64_t(bx) * 4, int64_t(by) * 4,
					 int64_t(bz) * 4};
		uint64_t m = masks[i * stride];
		while (m) {
			int b = __builtin_ctzll(m);
			m &= m - 1;
			const int64_t v[3] = {base[0] + tab.x[b], base[1] + tab.y[b],
					      base[2] + tab.z[b]};
			Coord q;
			if (c.same) {
				for (int a = 0; a < 3; a++)
					q[a] = int32_t(off[a] + (v[a] << shift) + half);
			} else {
				openvdb::Vec3d p;
				for (int a = 0; a < 3; a++)
					p[a] = double(off[a]) + double(v[a] << shift) + centre;
				openvdb::Vec3d ci =
					cxf.worldToIndex(c.density_xf->indexToWorld(p));
				q = Coord(round_index(ci[0]), round_index(ci[1]),
					  round_index(ci[2]));
			}
			V val;
			if (!acc.probeValue(q, val))
				val = bg; // inactive: the background
			for (int a = 0; a < 3; a++) {
				if constexpr (std::is_floating_point_v<E>)
					*rgb++ = colour_byte(double(val[a]));
				else
					*rgb++ = colour_byte(int32_t(val[a]));
			}
		}
	}
}

} // namespace

extern "C" int vd_vdb_colour_open(struct vd_vdb_colour **out, const char *path,
				  const char *name,
				  const struct vd_vdb *density,
				  struct vd_vdb_colour_info *info)
{
	*out = nullptr;
	try {
		init_once();
		std::string want;
		if (name)
			want = name;
		else if (int err = find_colour_grid(path, &want))
			return err;
		if (want.empty())
			return VD_OK; // no colour grid: no colours
		openvdb::GridBase::Ptr grid;
		if (int err = read_grid(path, want.c_str(), &grid))
			return err;
		if (colour_kind_of(*grid) == C_NONE)
			return vd_fail(VD_ERR_UNSUPPORTED, "colour grid '%s' holds "
				       "%s values; colours come from vec3s, vec3d "
				       "or vec3i grids", grid->getName().c_str(),
				       grid->valueType().c_str());
		auto *c = new vd_vdb_colour;
		c->grid = grid;
		c->density_xf = density->grid->constTransformPtr();
		c->same = grid->transform() == density->grid->transform();
		if (info) {
			std::memset(info, 0, sizeof *info);
			std::snprintf(info->grid_name, sizeof info->grid_name, "%s",
				      grid->getName().c_str());
			std::snprintf(info->value_type, sizeof info->value_type,
				      "%s", grid->valueType().c_str());
			info->same_transform = c->same;
		}
		*out = c;
		return VD_OK;
	} catch (const std::bad_alloc &) {
		return vd_fail(VD_ERR_NOMEM, "reading the colour grid");
	} catch (const std::exception &e) {
		return fail_exception("colour grid", e);
	}
}

extern "C" void vd_vdb_colour_close(struct vd_vdb_colour *c)
{
	delete c;
}

extern "C" int vd_vdb_colour_bricks(const struct vd_vdb_colour *c,
				    const int32_t off[3], int shift,
				    const uint64_t *keys, const uint64_t *masks,
				    size_t stride, size_t n, uint8_t *rgb)
{
	try {
		const openvdb::GridBase &g = *c->grid;
		switch (colour_kind_of(g)) {
		case C_VEC3S:
			colour_bricks(static_cast<const openvdb::Vec3SGrid &>(g), *c,
				      off, shift, keys, masks, stride, n, rgb);
			break;
		case C_VEC3D:
			colour_bricks(static_cast<const openvdb::Vec3DGrid &>(g), *c,
				      off, shift, keys, masks, stride, n, rgb);
			break;
		case C_VEC3I:
			colour_bricks(static_cast<const openvdb::Vec3IGrid &>(g), *c,
				      off, shift, keys, masks, stride, n, rgb);
			break;
		case C_NONE:
			return vd_fail(VD_ERR_INTERNAL, "not a colour grid");
		}
		return VD_OK;
	} catch (const std::exception &e) {
		return fail_exception("colour", e);
	}
}

// ------------------------------------------------------------ test support

extern "C" int vd_vdb_test_reference(const char *path,
				     const struct vd_vdb_select *sel,
				     int margin,
				     void (*fn)(void *ctx, int32_t x, int32_t y,
						int32_t z),
				     void *ctx, uint64_t *count)
{
	*count = 0;
	try {
		openvdb::GridBase::Ptr grid;
		int err = read_grid(path, sel->grid_name, &grid);
		if (err || (err = check_mode(*grid, sel->mode)))
			return err;
		CoordBBox bb = grid->evalActiveVoxelBoundingBox();
		if (bb.empty())
			return VD_OK;
		bb.expand(margin);
		dispatch(*grid, [&](const auto &g) {
			auto acc = g.getConstAccessor();
			auto in = [&](const Coord &c) {
				return selected(sel->mode, sel->fog_threshold,
						acc.getValue(c), acc.isValueOn(c));
			};
			for (auto it = bb.begin(); it; ++it) {
				Coord c = *it;
				bool s = in(c);
				if (s && sel->mode == VD_VDB_LEVELSET_SURFACE) {
					s = false;
					for (int a = 0; a < 3 && !s; a++)
						for (int d = -1; d <= 1 && !s; d += 2) {
							Coord q = c;
							q[a] += d;
							s = !inside(acc.getValue(q));
						}
				}
				if (s) {
					++*count;
					if (fn)
						fn(ctx, c.x(), c.y(), c.z());
				}
			}
		});
		return VD_OK;
	} catch (const std::exception &e) {
		return fail_exception("reference", e);
	}
}
