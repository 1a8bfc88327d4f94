// tsvdag_check: decodes a .tdag16 written by the transform-aware DAG
// reference code (Molenaar & Eisemann, I3D 2025) and compares its voxels
// with those of a SymVox .svdag (voxdag's), as the reference reads it.
//
//   tsvdag_check OURS.svdag THEIRS.tdag16
//
// Two checks, together an equality of the voxel sets:
//  - subset: every voxel of every non-empty 4^3 brick of the .svdag is
//    looked up in the .tdag16 read back from disk with the reference's own
//    decoder (TransformDAG16::get, as its verifyComplexTransformDAG does),
//    both set and unset ones;
//  - count: the .tdag16's voxels are counted by a decoder of our own that
//    follows get()'s rules (child index through the accumulated transform,
//    translation in the world frame, voxels shifted out of the child's cell
//    are empty, 4^3 masks transformed), expanding subtrees of height <= 4
//    (where translations live) into bitsets and summing counts above.
//    Equal counts and the subset check mean the two sets are equal.
// Prints one line: voxels_svdag=N voxels_tdag16=M bricks_checked=B
// mismatches=X; exit 0 when equal, 1 when not, 2 on usage.
//
// Compiled by tests/bench/vs_tsvdag.sh, outside the repository, as one
// translation unit with the reference's transform_dag_encoding.cpp (its
// transform tables are file-static); never built by make.
#include "transform_dag_encoding.cpp"

#include <cstdio>
#include <fstream>
#include <voxcom/voxel/export_ssvdag.h>
#include <unordered_map>

namespace {

struct Key {
    uint32_t level, node, transform;
    bool operator==(const Key&) const = default;
};
struct KeyHash {
    size_t operator()(const Key& k) const
    {
        return (size_t(k.level) * 0x9E3779B97F4A7C15ull) ^ (size_t(k.node) * 0xC2B2AE3D27D4EB4Full) ^ k.transform;
    }
};

// A cube of 2^level voxels per side, level <= 4, as a bitset indexed by
// x + (y << level) + (z << 2 * level).
using Cube = std::vector<uint64_t>;

struct Decoder {
    const TransformDAG16& dag;
    uint32_t maxTranslationLevel;
    std::unordered_map<Key, Cube, KeyHash> cubes;
    std::unordered_map<Key, uint64_t, KeyHash> counts;

    static bool getBit(const Cube& c, uint32_t i) { return (c[i >> 6] >> (i & 63)) & 1; }
    static void setBit(Cube& c, uint32_t i) { c[i >> 6] |= uint64_t(1) << (i & 63); }

    // Calls fn(v) for each voxel of cube c (side 2^l) moved by t that
    // stays inside the cube: a translation moves voxels out of the child's
    // cell, and those are empty.
    template <typename F>
    static void forEachMoved(const Cube& c, uint32_t l, glm::ivec3 t, F&& fn)
    {
        const uint32_t half = 1u << l;
        for (uint32_t z = 0; z < half; ++z)
            for (uint32_t y = 0; y < half; ++y)
                for (uint32_t x = 0; x < half; ++x) {
                    if (!getBit(c, x + (y << l) + (z << 2 * l)))
                        continue;
                    const glm::ivec3 v = glm::ivec3(x, y, z) + t;
                    if (glm::all(glm::greaterThanEqual(v, glm::ivec3(0))) && glm::all(glm::lessThan(v, glm::ivec3(int(half)))))
                        fn(v);
                }
    }

    // The voxels of node `node` at `level` seen through accumulated
    // transform `transform` (an index into allTransforms), in local
    // world-frame coordinates.
    const Cube& cube(uint32_t level, uint32_t node, uint32_t transform)
    {
        const Key key { level, node, transform };
        if (auto it = cubes.find(key); it != cubes.end())
            return it->second;
        const uint32_t side = 1u << level;
        Cube out((size_t(side) * side * side + 63) / 64, 0);
        if (level == dag.subGridLevel) {
            const uint64_t mask = applyTransformToBitMask4x4x4(dag.subGrids[node].bitmask, allTransforms[transform]);
            for (uint32_t z = 0; z < 4; ++z)
                for (uint32_t y = 0; y < 4; ++y)
                    for (uint32_t x = 0; x < 4; ++x)
                        if ((mask >> morton_encode32(glm::uvec3(x, y, z))) & 1)
                            setBit(out, x + (y << 2) + (z << 4));
        } else {
            const uint32_t childLevel = level - 1, half = side / 2;
            const uint16_t* pNode = &dag.nodesPerLevel[level][node];
            for (uint32_t worldChild = 0; worldChild < 8; ++worldChild) {
                const uint32_t storedChild = allTransforms[transform][worldChild];
                if (!dag.hasChild(pNode, storedChild))
                    continue;
                const auto ptr = dag.getChildPointer(level, pNode, storedChild);
                glm::ivec3 t { ptr.translation[0], ptr.translation[1], ptr.translation[2] };
                if (t != glm::ivec3(0)) {
                    const auto global = allTransformPointers[transform];
                    t = applyAxisPermutation(t, global.getAxisPermutation());
                    t = glm::mix(t, -t, global.getSymmetry());
                }
                const Cube& c = cube(childLevel, ptr.index, transformCombineTable[transform * 48 + ptr.transformID]);
                const glm::ivec3 origin = glm::ivec3(morton_decode32<3>(worldChild)) * int(half);
                forEachMoved(c, childLevel, t, [&](glm::ivec3 v) {
                    const glm::ivec3 w = origin + v;
                    setBit(out, uint32_t(w.x) + (uint32_t(w.y) << level) + (uint32_t(w.z) << 2 * level));
                });
            }
        }
        return cubes.emplace(key, std::move(out)).first->second;
    }

    uint64_t count(uint32_t level, uint32_t node, uint32_t transform)
    {
        if (level <= 4) {
            const Cube& c = cube(level, node, transform);
            uint64_t n = 0;
            for (uint64_t w : c)
                n += (uint64_t)std::popcount(w);
            return n;
        }
        const Key key { level, node, transform };
        if (auto it = counts.find(key); it != counts.end())
            return it->second;
        const uint16_t* pNode = &dag.nodesPerLevel[level][node];
        uint64_t n = 0;
        for (uint32_t child = 0; child < 8; ++child) {
            if (!dag.hasChild(pNode, child))
                continue;
            const auto ptr = dag.getChildPointer(level, pNode, child);
            const uint32_t childTransform = transformCombineTable[transform * 48 + ptr.transformID];
            glm::ivec3 t { ptr.translation[0], ptr.translation[1], ptr.translation[2] };
            // A count does not depend on the child's position, only on the
            // transform passed down and on a translation, which moves voxels
            // out of the child's cell (those are empty).
            if (t == glm::ivec3(0)) {
                n += count(level - 1, ptr.index, childTransform);
                continue;
            }
            if (level - 1 > 4) {
                std::fprintf(stderr, "tsvdag_check: translation to a child at level %u (above 4): not decoded\n", level - 1);
                std::exit(1);
            }
            const auto global = allTransformPointers[transform];
            t = applyAxisPermutation(t, global.getAxisPermutation());
            t = glm::mix(t, -t, global.getSymmetry());
            forEachMoved(cube(level - 1, ptr.index, childTransform), level - 1, t,
                         [&](glm::ivec3) { ++n; });
        }
        return counts.emplace(key, n).first->second;
    }
};

uint64_t bricksChecked = 0, mismatches = 0;

void subset(const EditStructure<void, uint32_t>& svdag, const TransformDAG16& dag, uint32_t level, uint32_t node, const glm::uvec3& pos)
{
    if (level == svdag.subGridLevel) {
        const auto& brick = svdag.subGrids[node];
        ++bricksChecked;
        for (uint32_t i = 0; i < 64; ++i) {
            const glm::uvec3 local = morton_decode32<3>(i);
            if (brick.get(local) != dag.get(glm::ivec3((pos << 2u) + local)))
                ++mismatches;
        }
        return;
    }
    const auto& n = svdag.nodesPerLevel[level][node];
    for (uint32_t c = 0; c < 8; ++c)
        if (n.children[c] != n.EmptyChild)
            subset(svdag, dag, level - 1, n.children[c], (pos << 1u) + morton_decode32<3>(c));
}

}

int main(int argc, char** argv)
{
    if (argc != 3) {
        std::fprintf(stderr, "usage: tsvdag_check OURS.svdag THEIRS.tdag16\n");
        return 2;
    }
    spdlog::set_level(spdlog::level::warn);
    Bounds bounds;
    const auto svdag = importSVDAG(argv[1], bounds);
    const uint64_t ours = svdag.computeVoxelCount();

    TransformDAG16 dag;
    {
        std::ifstream file { argv[2], std::ios::binary };
        if (!file) {
            std::fprintf(stderr, "tsvdag_check: cannot open '%s'\n", argv[2]);
            return 1;
        }
        BinaryReader reader { file };
        reader.read(dag);
    }
    if (dag.rootLevel != svdag.rootLevel) {
        std::fprintf(stderr, "tsvdag_check: root levels differ (%u, %u)\n", svdag.rootLevel, dag.rootLevel);
        return 1;
    }
    subset(svdag, dag, svdag.rootLevel, 0, glm::uvec3(0));
    Decoder decoder { dag, dag.constructionConfig.maxTranslationLevel, {}, {} };
    const uint64_t theirs = decoder.count(dag.rootLevel, 0, 0);
    std::printf("voxels_svdag=%llu voxels_tdag16=%llu bricks_checked=%llu mismatches=%llu\n",
        (unsigned long long)ours, (unsigned long long)theirs, (unsigned long long)bricksChecked, (unsigned long long)mismatches);
    return (ours == theirs && mismatches == 0) ? 0 : 1;
}
