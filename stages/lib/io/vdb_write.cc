// vdb_write.cc - the library's writing of OpenVDB files: vdb-export's
// grid and the test grids (tests/unit/test_vdb.c, vdb-make-test-grids).
// Every entry point catches every exception, as in vdb.cc.
#include "io/vdb_shim.h"
#include "io/vdb_test_grids.h"

#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/MeshToVolume.h>

#include <fcntl.h>
#include <ostream>
#include <streambuf>
#include <unistd.h>

using openvdb::Coord;
using openvdb::CoordBBox;
using vd_shim::brick_table;
using vd_shim::fail_exception;
using vd_shim::init_once;

// ------------------------------------------------------------------ export

namespace {

// An output stream onto a file descriptor that keeps the errno of its
// first failed write: io::File::write writes through an std::ofstream and
// never checks it, so a full disk gave a cut .vdb and exit 0.
class fd_buf : public std::streambuf {
public:
	explicit fd_buf(int fd) : fd_(fd) { setp(buf_, buf_ + sizeof buf_); }
	int error() const { return err_; }
	// Writes what is buffered; false (error() set) on failure.
	bool drain()
	{
		const char *p = pbase();
		while (!err_ && p < pptr()) {
			ssize_t n = ::write(fd_, p, size_t(pptr() - p));
			if (n < 0 && errno == EINTR)
				continue;
			if (n <= 0)
				err_ = n < 0 ? errno : EIO;
			else
				p += n;
		}
		setp(buf_, buf_ + sizeof buf_);
		return !err_;
	}

protected:
	int_type overflow(int_type c) override
	{
		if (!drain())
			return traits_type::eof();
		if (!traits_type::eq_int_type(c, traits_type::eof()))
			sputc(traits_type::to_char_type(c));
		return traits_type::not_eof(c);
	}
	int sync() override { return drain() ? 0 : -1; }
	// Archive::write seeks back to fill in each grid's offsets
	pos_type seekoff(off_type off, std::ios_base::seekdir dir,
			 std::ios_base::openmode) override
	{
		if (!drain())
			return pos_type(off_type(-1));
		int whence = dir == std::ios_base::beg ? SEEK_SET
			     : dir == std::ios_base::cur ? SEEK_CUR : SEEK_END;
		off_t r = ::lseek(fd_, off_t(off), whence);
		return r < 0 ? pos_type(off_type(-1)) : pos_type(off_type(r));
	}
	pos_type seekpos(pos_type p, std::ios_base::openmode m) override
	{
		return seekoff(off_type(p), std::ios_base::beg, m);
	}

private:
	int fd_, err_ = 0;
	char buf_[1 << 16];
};

// io::File's own write is Archive::write(stream, grids, seekable = true)
// on an ofstream; the same call on our stream gives the same bytes.
class checked_file : public openvdb::io::File {
public:
	using openvdb::io::File::File;
	void write_to(std::ostream &os, const openvdb::GridPtrVec &grids) const
	{
		openvdb::io::Archive::write(os, grids, /*seekable=*/true);
	}
};

// Writes grids to `path` through vd_atomic_* (fsync, rename, directory
// fsync) with every write checked; VD_ERR_IO naming the cause otherwise.
// The caller catches; the temporary is removed on every way out,
// exceptions included.
int write_vdb_checked(const char *path, const openvdb::GridPtrVec &grids)
{
	struct vd_atomic a;
	if (int err = vd_atomic_open(&a, path))
		return err;
	struct guard {
		vd_atomic *a;
		~guard() { vd_atomic_abort(a); } // no-op after commit
	} g{&a};
	int e;
	{
		// straight onto the descriptor: a.f's buffer stays unused
		fd_buf buf(fileno(a.f));
		std::ostream os(&buf);
		checked_file(a.tmp).write_to(os, grids);
		os.flush();
		e = buf.drain() ? 0 : buf.error();
	}
	if (e)
		return vd_fail(VD_ERR_IO, "cannot write '%s': %s", a.tmp,
			       std::strerror(e));
	return vd_atomic_commit(&a);
}

} // namespace

extern "C" int vd_vdb_export(const char *path, const char *grid_name,
			     int levels, const struct vd_transform *t,
			     int (*next)(void *ctx, const uint64_t **keys,
					 const uint64_t **masks, size_t *n),
			     void *ctx, uint64_t *voxels)
{
	static const brick_table tab;
	if (levels < 1 || levels > VD_MAX_LEVELS)
		return vd_fail(VD_ERR_RANGE, "levels %d outside 1..%d", levels,
			       VD_MAX_LEVELS);
	if (!(t->voxel_size > 0) || !std::isfinite(t->voxel_size))
		return vd_fail(VD_ERR_RANGE, "voxel size %g", t->voxel_size);
	const int brick_bits = levels >= 2 ? 3 * (levels - 2) : 0;
	try {
		init_once();
		auto grid = openvdb::BoolGrid::create(false);
		grid->setName(grid_name);
		const double vs = t->voxel_size;
		auto xf = openvdb::math::Transform::createLinearTransform(vs);
		// our voxel v spans [origin + v vs, origin + (v+1) vs); OpenVDB
		// centres index v at translation + v vs
		xf->postTranslate(openvdb::Vec3d(t->origin[0] + vs / 2,
						 t->origin[1] + vs / 2,
						 t->origin[2] + vs / 2));
		grid->setTransform(xf);
		grid->insertMeta("voxdag_levels", openvdb::Int32Metadata(levels));
		auto acc = grid->getAccessor();
		for (;;) {
			const uint64_t *keys, *masks;
			size_t n = 0;
			int err = next(ctx, &keys, &masks, &n);
			if (err)
				return err;
			if (n == 0)
				break;
			for (size_t i = 0; i < n; i++) {
				if (keys[i] >> brick_bits)
					return vd_fail(VD_ERR_CORRUPT, "brick key "
						       "%llx outside a grid of "
						       "depth %d",
						       (unsigned long long)keys[i],
						       levels);
				uint64_t m = masks[i];
				if (!m)
					continue;
				uint32_t bx, by, bz;
				vd_morton3_decode(keys[i], &bx, &by, &bz);
				Coord base(int(bx) * 4, int(by) * 4, int(bz) * 4);
				auto *leaf = acc.touchLeaf(base);
				while (m) {
					int b = __builtin_ctzll(m);
					m &= m - 1;
					leaf->setValueOn(base.offsetBy(tab.x[b], tab.y[b],
								       tab.z[b]),
							 true);
				}
			}
		}
		grid->tree().prune();
		if (voxels)
			*voxels = grid->activeVoxelCount();
		openvdb::GridPtrVec grids{grid};
		return write_vdb_checked(path, grids);
	} catch (const std::bad_alloc &) {
		return vd_fail(VD_ERR_NOMEM, "building the grid");
	} catch (const std::exception &e) {
		return vd_fail(VD_ERR_IO, "cannot write '%s': OpenVDB: %s", path,
			       e.what());
	}
}

// ------------------------------------------------------------ test support

struct vd_vdb_test_file {
	openvdb::GridPtrVec grids;
};

#define TEST_TRY(what, body)                                                 \
	try {                                                                \
		init_once();                                                 \
		body                                                         \
		return VD_OK;                                                \
	} catch (const std::exception &e) {                                  \
		return fail_exception(what, e);                              \
	}

extern "C" int vd_vdb_test_new(struct vd_vdb_test_file **f)
{
	TEST_TRY("test file", *f = new vd_vdb_test_file;)
}

extern "C" void vd_vdb_test_free(struct vd_vdb_test_file *f)
{
	delete f;
}

extern "C" int vd_vdb_test_add_sphere(struct vd_vdb_test_file *f,
				      const char *name, double radius,
				      const double c[3], double voxel_size,
				      double half_width)
{
	TEST_TRY("sphere", {
		auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
			float(radius), openvdb::Vec3f(float(c[0]), float(c[1]), float(c[2])),
			float(voxel_size), float(half_width));
		g->setName(name);
		f->grids.push_back(g);
	})
}

extern "C" int vd_vdb_test_add_fog_box(struct vd_vdb_test_file *f,
				       const char *name, const int32_t lo[3],
				       const int32_t hi[3], float value,
				       const int32_t ilo[3], const int32_t ihi[3],
				       float inner_value)
{
	TEST_TRY("fog box", {
		auto g = openvdb::FloatGrid::create(0.f);
		g->setName(name);
		g->setGridClass(openvdb::GRID_FOG_VOLUME);
		g->tree().fill(CoordBBox(Coord(lo[0], lo[1], lo[2]),
					 Coord(hi[0], hi[1], hi[2])),
			       value, true);
		if (ilo[0] <= ihi[0])
			g->tree().fill(CoordBBox(Coord(ilo[0], ilo[1], ilo[2]),
						 Coord(ihi[0], ihi[1], ihi[2])),
				       inner_value, true);
		f->grids.push_back(g);
	})
}

extern "C" int vd_vdb_test_add_mesh(struct vd_vdb_test_file *f,
				    const char *name, const char *mesh_path,
				    int resolution, double half_width)
{
	struct vd_mesh *m;
	int err = vd_mesh_open(&m, mesh_path);
	if (err)
		return err;
	try {
		init_once();
		std::vector<openvdb::Vec3s> pts;
		std::vector<openvdb::Vec3I> tris;
		std::vector<vd_triangle> buf(4096);
		size_t n;
		float lo[3] = {INFINITY, INFINITY, INFINITY};
		float hi[3] = {-INFINITY, -INFINITY, -INFINITY};
		while (!(err = vd_mesh_read(m, buf.data(), buf.size(), &n)) && n) {
			for (size_t i = 0; i < n; i++) {
				auto b = openvdb::Index32(pts.size());
				for (int k = 0; k < 3; k++) {
					const float *v = buf[i].v[k];
					pts.emplace_back(v[0], v[1], v[2]);
					for (int a = 0; a < 3; a++) {
						lo[a] = std::min(lo[a], v[a]);
						hi[a] = std::max(hi[a], v[a]);
					}
				}
				tris.emplace_back(b, b + 1, b + 2);
			}
		}
		vd_mesh_close(m);
		if (err)
			return err;
		if (tris.empty())
			return vd_fail(VD_ERR_EMPTY, "'%s' has no triangles", mesh_path);
		float ext = std::max(hi[0] - lo[0], std::max(hi[1] - lo[1], hi[2] - lo[2]));
		auto xf = openvdb::math::Transform::createLinearTransform(
			double(ext) / resolution);
		auto g = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(
			*xf, pts, tris, float(half_width));
		g->setName(name);
		f->grids.push_back(g);
		return VD_OK;
	} catch (const std::exception &e) {
		return fail_exception("mesh to level set", e);
	}
}

extern "C" int vd_vdb_test_add_empty(struct vd_vdb_test_file *f,
				     const char *name)
{
	TEST_TRY("empty grid", {
		auto g = openvdb::FloatGrid::create(0.f);
		g->setName(name);
		f->grids.push_back(g);
	})
}

extern "C" int vd_vdb_test_add_transformed(struct vd_vdb_test_file *f,
					   const char *name, int n,
					   double rotate_deg, double sx,
					   double sy, double sz)
{
	TEST_TRY("transformed grid", {
		auto g = openvdb::FloatGrid::create(0.f);
		g->setName(name);
		g->tree().fill(CoordBBox(Coord(0), Coord(n - 1)), 1.f, true);
		auto xf = openvdb::math::Transform::createLinearTransform(1.0);
		xf->preScale(openvdb::Vec3d(sx, sy, sz));
		if (rotate_deg != 0)
			xf->postRotate(rotate_deg * M_PI / 180, openvdb::math::Z_AXIS);
		g->setTransform(xf);
		f->grids.push_back(g);
	})
}

extern "C" void vd_vdb_test_colour_of(int64_t x, int64_t y, int64_t z,
				      uint8_t rgb[3])
{
	rgb[0] = uint8_t(uint64_t(37 * x + 11) & 255);
	rgb[1] = uint8_t(uint64_t(59 * y + 3 * x + 23) & 255);
	rgb[2] = uint8_t(uint64_t(17 * z + 5 * y + 7) & 255);
}

namespace {

template <typename GridT>
void add_colour(vd_vdb_test_file *f, const char *name, double voxel_size,
		const double tr[3], const int32_t lo[3], const int32_t hi[3],
		const int32_t off_lo[3], const int32_t off_hi[3],
		const uint8_t bg[3])
{
	using V = typename GridT::ValueType;
	using E = typename V::value_type;
	auto enc = [](const uint8_t c[3]) {
		if constexpr (std::is_floating_point_v<E>)
			return V(E(c[0]) / E(255), E(c[1]) / E(255), E(c[2]) / E(255));
		else
			return V(E(c[0]), E(c[1]), E(c[2]));
	};
	auto g = GridT::create(enc(bg));
	g->setName(name);
	auto xf = openvdb::math::Transform::createLinearTransform(voxel_size);
	xf->postTranslate(openvdb::Vec3d(tr[0], tr[1], tr[2]));
	g->setTransform(xf);
	auto acc = g->getAccessor();
	for (int32_t x = lo[0]; x <= hi[0]; x++)
		for (int32_t y = lo[1]; y <= hi[1]; y++)
			for (int32_t z = lo[2]; z <= hi[2]; z++) {
				uint8_t c[3];
				vd_vdb_test_colour_of(x, y, z, c);
				acc.setValueOn(Coord(x, y, z), enc(c));
			}
	// inactive but not the background: the import must not read these
	for (int32_t x = off_lo[0]; x <= off_hi[0]; x++)
		for (int32_t y = off_lo[1]; y <= off_hi[1]; y++)
			for (int32_t z = off_lo[2]; z <= off_hi[2]; z++)
				acc.setValueOff(Coord(x, y, z));
	f->grids.push_back(g);
}

} // namespace

extern "C" int vd_vdb_test_add_colour(struct vd_vdb_test_file *f,
				      const char *name, const char *type,
				      double voxel_size, const double tr[3],
				      const int32_t lo[3], const int32_t hi[3],
				      const int32_t off_lo[3],
				      const int32_t off_hi[3], const uint8_t bg[3])
{
	TEST_TRY("colour grid", {
		std::string t = type;
		if (t == "vec3s")
			add_colour<openvdb::Vec3SGrid>(f, name, voxel_size, tr, lo, hi,
						       off_lo, off_hi, bg);
		else if (t == "vec3d")
			add_colour<openvdb::Vec3DGrid>(f, name, voxel_size, tr, lo, hi,
						       off_lo, off_hi, bg);
		else if (t == "vec3i")
			add_colour<openvdb::Vec3IGrid>(f, name, voxel_size, tr, lo, hi,
						       off_lo, off_hi, bg);
		else
			return vd_fail(VD_ERR_ARG, "colour grid type '%s'", type);
	})
}

namespace {

template <typename GridT>
void add_colour_values(vd_vdb_test_file *f, const char *name, int n,
		       const double *v)
{
	using V = typename GridT::ValueType;
	using E = typename V::value_type;
	auto g = GridT::create(V(E(0), E(0), E(0)));
	g->setName(name);
	for (int i = 0; i < n; i++)
		g->tree().setValueOn(Coord(i, 0, 0),
				     V(E(v[3 * i]), E(v[3 * i + 1]), E(v[3 * i + 2])));
	f->grids.push_back(g);
}

} // namespace

extern "C" int vd_vdb_test_add_colour_values(struct vd_vdb_test_file *f,
					     const char *name, const char *type,
					     int n, const double *values)
{
	TEST_TRY("colour values", {
		std::string t = type;
		if (t == "vec3s")
			add_colour_values<openvdb::Vec3SGrid>(f, name, n, values);
		else if (t == "vec3d")
			add_colour_values<openvdb::Vec3DGrid>(f, name, n, values);
		else if (t == "vec3i")
			add_colour_values<openvdb::Vec3IGrid>(f, name, n, values);
		else
			return vd_fail(VD_ERR_ARG, "colour grid type '%s'", type);
	})
}

extern "C" int vd_vdb_test_write(struct vd_vdb_test_file *f, const char *path)
{
	TEST_TRY("write", {
		openvdb::io::File file(path);
		file.write(f->grids);
		file.close();
	})
}
