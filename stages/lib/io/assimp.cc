// assimp.cc - glTF 2.0, FBX, Collada and 3DS scenes through Assimp, behind
// the C interface of vd_mesh.h's "imported formats" section. Only
// voxelize-assimp references vd_assimp_import, so only it links libassimp
// (about 4 MB of memory at start that mesh runs should not pay).
//
// The scene is read whole (Assimp has no streaming reader), triangulated
// and pre-transformed into world space, then copied into a plain C
// vd_import_scene and Assimp's copy freed before returning. Every
// exception is caught here: the caller gets an error code and one detail
// line.
//
// Decisions worth knowing:
// - Colour per material: the diffuse colour (AI_MATKEY_COLOR_DIFFUSE, which
//   Assimp's glTF reader fills with baseColorFactor), else the base
//   colour; the texture is the first diffuse texture, else the first base
//   colour texture, sampled with UV channel 0 and the material's wrap
//   modes. glTF states its factors and vertex colours in linear light, so
//   they are converted to sRGB (what the rule stores and what a viewer
//   shows); the other formats' colours are taken as sRGB, as OBJ's Kd.
// - Assimp gives a scene without materials a default one (named
//   AI_DEFAULT_MATERIAL_NAME): that counts as no material, so such a
//   scene has no colours, as a plain OBJ.
// - Assimp's UVs have v = 0 at the image's bottom (it flips glTF's), our
//   sampler's convention.
#include "voxdag.h"
#include "io/mesh/mesh_import.h"

#include <assimp/DefaultIOSystem.h>
#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <map>
#include <new>
#include <string>
#include <strings.h>
#include <sys/stat.h>
#include <vector>

namespace {

char *dup(const char *s)
{
	char *p = strdup(s);
	if (!p)
		throw std::bad_alloc();
	return p;
}

template <class T> T *alloc(size_t n)
{
	T *p = static_cast<T *>(calloc(n ? n : 1, sizeof(T)));
	if (!p)
		throw std::bad_alloc();
	return p;
}

// Assimp opens the files a scene pulls in (a .gltf's buffers, ...)
// through its IOSystem: this one records each, hashed just before it is
// opened, and each name it looked for in vain, for voxelize's list of
// sources (sources.c). The scene file itself is left out: the runner's key
// covers it, and hashing it would read a large scene once more.
class RecordingIO : public Assimp::DefaultIOSystem {
public:
	RecordingIO(const char *scene, std::vector<vd_mesh_source> *list)
		: scene_(scene), list_(list)
	{
		struct stat st;
		have_scene_ = stat(scene, &st) == 0;
		if (have_scene_) {
			dev_ = st.st_dev;
			ino_ = st.st_ino;
		}
	}

	bool Exists(const char *file) const override
	{
		bool there = DefaultIOSystem::Exists(file);
		if (!there)
			note(file);
		return there;
	}

	Assimp::IOStream *Open(const char *file, const char *mode) override
	{
		note(file);
		return DefaultIOSystem::Open(file, mode);
	}

private:
	void note(const char *file) const
	{
		struct stat st;
		if (!strcmp(file, scene_.c_str()) ||
		    (have_scene_ && stat(file, &st) == 0 && st.st_dev == dev_ &&
		     st.st_ino == ino_))
			return;
		for (const vd_mesh_source &r : *list_)
			if (!strcmp(r.path, file))
				return;
		vd_mesh_source r = {};
		r.path = dup(file);
		r.found = vd_source_xxh3(file, &r.xxh3, &r.size) == VD_OK;
		if (!r.found) {
			vd_error_clear();
			r.xxh3 = r.size = 0;
		}
		try {
			list_->push_back(r);
		} catch (...) {
			free(r.path);
			throw;
		}
	}

	std::string scene_;
	std::vector<vd_mesh_source> *list_;
	bool have_scene_;
	dev_t dev_ = 0;
	ino_t ino_ = 0;
};

// Owns the recorded paths until they are handed to the scene.
struct SourceList {
	std::vector<vd_mesh_source> v;
	~SourceList()
	{
		for (vd_mesh_source &r : v)
			free(r.path);
	}
};

// glTF's linear values to sRGB bytes (the sRGB transfer function).
uint8_t byte_of(float x, bool linear)
{
	double v = x;
	if (!(v > 0))
		return 0;
	if (v >= 1)
		return 255;
	if (linear)
		v = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
	return static_cast<uint8_t>(v * 255.0 + 0.5);
}

uint8_t wrap_of(aiTextureMapMode m)
{
	switch (m) {
	case aiTextureMapMode_Clamp:
	case aiTextureMapMode_Decal: // outside is "no texture": the edge is nearest
		return VD_WRAP_CLAMP;
	case aiTextureMapMode_Mirror:
		return VD_WRAP_MIRROR;
	default:
		return VD_WRAP_REPEAT;
	}
}

bool has_ext(const char *path, const char *ext)
{
	size_t n = strlen(path), e = strlen(ext);
	return n > e && !strcasecmp(path + n - e, ext);
}

// The scene's texture `name` (a file name, or "*N" / a name Assimp keeps
// embedded) as an index into s->texs, added once.
int texture_of(const aiScene *sc, const char *name, vd_import_scene *s,
	       std::map<std::string, int> &seen, size_t cap)
{
	auto it = seen.find(name);
	if (it != seen.end())
		return it->second;
	if (s->ntexs == cap)
		return -1;
	vd_import_texture *t = &s->texs[s->ntexs];
	const aiTexture *emb = sc->GetEmbeddedTexture(name);
	if (emb) {
		t->name = dup(name);
		if (emb->mHeight == 0 && emb->mWidth > 0) {
			// compressed: mWidth bytes of a PNG, JPEG, ... file
			t->bytes = emb->mWidth;
			t->data = alloc<uint8_t>(t->bytes);
			memcpy(t->data, emb->pcData, t->bytes);
		} else {
			t->unsupported = 1;
		}
	} else {
		t->path = dup(name);
		t->name = dup(name);
	}
	int i = static_cast<int>(s->ntexs++);
	seen[name] = i;
	return i;
}

void read_material(const aiScene *sc, const aiMaterial *mat, bool linear,
		   vd_import_scene *s, vd_import_material *m,
		   std::map<std::string, int> &seen, size_t tex_cap)
{
	m->tex = -1;
	m->rgb[0] = m->rgb[1] = m->rgb[2] = VD_GREY;
	aiString name;
	if (mat->Get(AI_MATKEY_NAME, name) == AI_SUCCESS &&
	    !strcmp(name.C_Str(), AI_DEFAULT_MATERIAL_NAME))
		return;
	aiColor4D c;
	if (aiGetMaterialColor(mat, AI_MATKEY_COLOR_DIFFUSE, &c) == AI_SUCCESS ||
	    aiGetMaterialColor(mat, AI_MATKEY_BASE_COLOR, &c) == AI_SUCCESS) {
		m->rgb[0] = byte_of(c.r, linear);
		m->rgb[1] = byte_of(c.g, linear);
		m->rgb[2] = byte_of(c.b, linear);
		s->has_colours = 1;
	}
	for (aiTextureType type : {aiTextureType_DIFFUSE,
				   aiTextureType_BASE_COLOR}) {
		if (mat->GetTextureCount(type) == 0)
			continue;
		aiString path;
		aiTextureMapMode mode[2] = {aiTextureMapMode_Wrap,
					    aiTextureMapMode_Wrap};
		if (mat->GetTexture(type, 0, &path, nullptr, nullptr, nullptr,
				    nullptr, mode) != AI_SUCCESS ||
		    !path.length)
			continue;
		m->tex = texture_of(sc, path.C_Str(), s, seen, tex_cap);
		m->wrap[0] = wrap_of(mode[0]);
		m->wrap[1] = wrap_of(mode[1]);
		s->has_colours = 1;
		break;
	}
}

int import(const char *path, vd_import_scene *s)
{
	SourceList files;
	Assimp::Importer imp;
	imp.SetIOHandler(new RecordingIO(path, &files.v)); // imp deletes it
	// points and lines bound no area: dropped here, counted below
	const aiScene *sc = imp.ReadFile(path, aiProcess_Triangulate |
					 aiProcess_PreTransformVertices |
					 aiProcess_ValidateDataStructure);
	if (!sc)
		return vd_fail(VD_ERR_FORMAT, "Assimp: %s", imp.GetErrorString());
	s->sources = alloc<vd_mesh_source>(files.v.size());
	for (vd_mesh_source &r : files.v) {
		s->sources[s->nsources++] = r;
		r.path = nullptr; // the scene's now
	}
	if (sc->mFlags & AI_SCENE_FLAGS_INCOMPLETE)
		return vd_fail(VD_ERR_FORMAT, "Assimp read an incomplete scene "
			       "(no meshes)");
	bool linear = has_ext(path, ".gltf") || has_ext(path, ".glb");
	const char *ext = strrchr(path, '.');
	snprintf(s->format, sizeof s->format, "%s (assimp)", ext ? ext + 1 : "?");
	for (char *p = s->format; *p; p++)
		*p = static_cast<char>(*p >= 'A' && *p <= 'Z' ? *p + 32 : *p);

	uint64_t nv = 0, nt = 0;
	for (unsigned i = 0; i < sc->mNumMeshes; i++) {
		const aiMesh *me = sc->mMeshes[i];
		nv += me->mNumVertices;
		for (unsigned f = 0; f < me->mNumFaces; f++) {
			unsigned k = me->mFaces[f].mNumIndices;
			nt += k >= 3 ? k - 2 : 0;
		}
	}
	if (nv > UINT32_MAX)
		return vd_fail(VD_ERR_RANGE, "the scene has %llu vertices (at "
			       "most 2^32 - 1)", (unsigned long long)nv);
	s->pos = alloc<float>(3 * nv);
	s->uv = alloc<float>(2 * nv);
	s->rgb = alloc<uint8_t>(4 * nv);
	s->idx = alloc<uint32_t>(3 * nt);
	s->mat = alloc<int32_t>(nt);
	s->mats = alloc<vd_import_material>(sc->mNumMaterials);
	size_t tex_cap = 2 * static_cast<size_t>(sc->mNumMaterials);
	s->texs = alloc<vd_import_texture>(tex_cap);
	std::map<std::string, int> seen;
	for (unsigned i = 0; i < sc->mNumMaterials; i++)
		read_material(sc, sc->mMaterials[i], linear, s, &s->mats[i],
			      seen, tex_cap);
	s->nmats = sc->mNumMaterials;

	uint64_t v0 = 0;
	for (unsigned i = 0; i < sc->mNumMeshes; i++) {
		const aiMesh *me = sc->mMeshes[i];
		const aiVector3D *uv = me->mTextureCoords[0];
		const aiColor4D *col = me->mColors[0];
		for (unsigned j = 0; j < me->mNumVertices; j++) {
			uint64_t v = v0 + j;
			s->pos[3 * v] = me->mVertices[j].x;
			s->pos[3 * v + 1] = me->mVertices[j].y;
			s->pos[3 * v + 2] = me->mVertices[j].z;
			uint8_t flags = 0;
			if (uv) {
				s->uv[2 * v] = uv[j].x;
				s->uv[2 * v + 1] = uv[j].y;
				flags |= 2;
			}
			if (col) {
				s->rgb[4 * v] = byte_of(col[j].r, linear);
				s->rgb[4 * v + 1] = byte_of(col[j].g, linear);
				s->rgb[4 * v + 2] = byte_of(col[j].b, linear);
				flags |= 1;
				s->has_colours = 1;
			}
			s->rgb[4 * v + 3] = flags;
		}
		int32_t mi = me->mMaterialIndex < sc->mNumMaterials
			? static_cast<int32_t>(me->mMaterialIndex) : -1;
		for (unsigned f = 0; f < me->mNumFaces; f++) {
			const aiFace &fa = me->mFaces[f];
			if (fa.mNumIndices < 3) {
				s->faces_dropped_short++;
				continue;
			}
			for (unsigned k = 1; k + 1 < fa.mNumIndices; k++) {
				unsigned c[3] = {fa.mIndices[0], fa.mIndices[k],
						 fa.mIndices[k + 1]};
				for (int j = 0; j < 3; j++) {
					if (c[j] >= me->mNumVertices)
						return vd_fail(VD_ERR_FORMAT, "mesh %u "
							       "face %u uses vertex "
							       "%u of %u", i, f, c[j],
							       me->mNumVertices);
					s->idx[3 * s->ntris + j] =
						static_cast<uint32_t>(v0 + c[j]);
				}
				s->mat[s->ntris] = mi;
				s->ntris++;
			}
		}
		v0 += me->mNumVertices;
	}
	s->nverts = nv;
	if (s->ntris == 0)
		return vd_fail(VD_ERR_EMPTY, "'%s' has no triangles", path);
	return VD_OK;
}

} // namespace

int vd_assimp_import(const char *path, struct vd_import_scene *out)
{
	memset(out, 0, sizeof *out);
	int err;
	try {
		err = import(path, out);
	} catch (const std::bad_alloc &) {
		err = vd_fail(VD_ERR_NOMEM, "reading the scene with Assimp");
	} catch (const std::exception &e) {
		err = vd_fail(VD_ERR_FORMAT, "Assimp: %s", e.what());
	} catch (...) {
		err = vd_fail(VD_ERR_FORMAT, "Assimp failed (an unknown "
			      "exception)");
	}
	if (err)
		vd_import_scene_release(out);
	return err;
}
