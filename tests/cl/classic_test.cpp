// The dissertation's generators on PoCL against the exact CPU reference of their semantics
// (global, or chunk-local with the solid padding shell), and JFA against an independent
// CPU implementation of the same propagation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "cl_test_util.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield {
namespace {

using ocl::Algorithm;
using test::pocl;

const Format kFormats[] = {Format::u8, Format::u16, Format::u32, Format::packed32};

// Algorithms exact for their semantics; lod and monolithic with a focus covering the world.
const Algorithm kExact[] = {Algorithm::brute,     Algorithm::brute_chunked, Algorithm::fim_host,
                            Algorithm::fim,       Algorithm::jfa_fim,       Algorithm::lod,
                            Algorithm::monolithic};
const Algorithm kJfa[] = {Algorithm::jfa, Algorithm::jfa_host};

ocl::GeneratorOptions options(Algorithm a, Format f, std::uint32_t chunk, Dims dims,
                              bool full_focus = true) {
    ocl::GeneratorOptions o;
    o.algorithm = a;
    o.format = f;
    o.chunk = chunk;
    if (full_focus && (a == Algorithm::lod || a == Algorithm::monolithic)) {
        const std::uint32_t c = chunk != 0 ? chunk : ocl::kDefaultChunk;
        const std::int64_t most = std::max({dims.x, dims.y, dims.z}) / c + 1;
        o.focus = Focus{{0, 0, 0}, most};
    }
    return ocl::resolve_options(o, dims);
}

World random_world(std::mt19937_64& rng, Dims d, double density) {
    World w(d);
    for (auto& v : w.voxels()) {
        v = static_cast<double>(rng() >> 11) * 0x1.0p-53 < density
                ? static_cast<std::uint8_t>(1 + rng() % 255)
                : 0;
    }
    return w;
}

std::string describe(const ocl::GeneratorOptions& o, const World& w) {
    return ocl::to_string(o.algorithm) + " " + w.dims().to_string() +
           (o.chunk != 0 ? " chunk " + std::to_string(o.chunk) : " global") + " format " +
           to_string(o.format) + " jfa+" + std::to_string(o.jfa_extra);
}

void expect_matches(const World& w, const Palette& palette, const ocl::GeneratorOptions& o,
                    const std::vector<std::uint32_t>& want_distances, const std::string& what) {
    const auto want = encode_field(want_distances, w, palette, o.format);
    const auto got = ocl::generate(pocl(), w, palette, o).bytes;
    const std::string diff = test::first_difference(got, want, o.format, w.dims());
    EXPECT_TRUE(diff.empty()) << what << " " << describe(o, w) << ": " << diff;
}

// Largest power of two <= every axis, capped at `cap`.
std::uint32_t chunk_for(Dims d, std::uint32_t cap) {
    std::uint32_t c = 1;
    while (c * 2 <= std::min({d.x, d.y, d.z, cap})) {
        c *= 2;
    }
    return c;
}

TEST(Classic, ExactAlgorithmsMatchReferenceOnRandomGrids) {
    std::mt19937_64 rng(4242);
    const double densities[] = {0.0, 0.0005, 0.01, 0.05, 0.2, 0.5, 1.0};
    int checked = 0;
    for (int trial = 0; trial < 28; ++trial) {
        const Dims d{static_cast<std::uint32_t>(1 + rng() % 40),
                     static_cast<std::uint32_t>(1 + rng() % 40),
                     static_cast<std::uint32_t>(1 + rng() % 40)};
        const World w = random_world(rng, d, densities[static_cast<std::size_t>(trial) % 7]);
        const std::uint32_t chunk = chunk_for(d, 1u << (rng() % 5));
        const auto global = reference_manhattan(w);
        const auto local = reference_manhattan_chunked(w, chunk);
        // All formats on every fourth grid, u16 (or u8 when distances are small) otherwise.
        for (Format f : kFormats) {
            if (trial % 4 != 0 && f != (trial % 2 == 0 ? Format::u16 : Format::u8)) {
                continue;
            }
            for (Algorithm a : kExact) {
                if (!ocl::always_chunked(a)) {
                    expect_matches(w, Palette(), options(a, f, 0, d), global, "global");
                }
                expect_matches(w, Palette(), options(a, f, chunk, d), local, "chunk-local");
                ++checked;
            }
        }
        if (HasFailure()) {
            return;
        }
    }
    EXPECT_GE(checked, 200);
}

TEST(Classic, BundledModels) {
    int models = 0;
    for (const auto& entry :
         std::filesystem::directory_iterator(std::filesystem::path(VOXFIELD_DATA_DIR) / "vox")) {
        if (entry.path().extension() != ".vox") {
            continue;
        }
        const VoxModel m = read_vox(entry.path());
        const Dims d = m.world.dims();
        const std::uint32_t chunk = chunk_for(d, 16);
        const auto global = reference_manhattan(m.world);
        const auto local = reference_manhattan_chunked(m.world, chunk);
        for (Algorithm a : kExact) {
            // Global brute force on the larger models takes minutes on 2 cores.
            if (a == Algorithm::brute && d.count() > 100000) {
                continue;
            }
            const Format f = a == Algorithm::monolithic ? Format::packed32 : Format::u16;
            if (!ocl::always_chunked(a)) {
                expect_matches(m.world, m.palette, options(a, f, 0, d), global,
                               entry.path().filename().string());
            }
            expect_matches(m.world, m.palette, options(a, f, chunk, d), local,
                           entry.path().filename().string());
        }
        ++models;
    }
    EXPECT_GE(models, 4);
}

// Jump flooding written independently on the CPU: the same 27-neighbourhood, steps
// next_pow2(extent)/2 ... 1 then the JFA+ extras, nearest by (distance, index), candidates
// restricted to the voxel's chunk (or the world), then the shell distance.
std::vector<std::uint32_t> cpu_jfa(const World& w, std::uint32_t chunk, std::uint32_t extra) {
    const Dims d = w.dims();
    const std::int64_t X = d.x, Y = d.y, Z = d.z;
    const std::uint32_t none = 0xFFFFFFFFu;
    std::vector<std::uint32_t> seed(w.size()), next(w.size());
    for (std::size_t i = 0; i < w.size(); ++i) {
        seed[i] = w.voxels()[i] != 0 ? static_cast<std::uint32_t>(i) : none;
    }
    auto l1 = [&](std::int64_t x, std::int64_t y, std::int64_t z, std::uint32_t s) {
        const std::int64_t sx = s % X, sy = s / X % Y, sz = s / X / Y;
        return std::llabs(sx - x) + std::llabs(sy - y) + std::llabs(sz - z);
    };
    auto bounds = [&](std::int64_t p, std::int64_t n) {
        if (chunk == 0) {
            return std::pair<std::int64_t, std::int64_t>{0, n};
        }
        const std::int64_t lo = p / chunk * chunk;
        return std::pair<std::int64_t, std::int64_t>{lo, std::min<std::int64_t>(lo + chunk, n)};
    };
    std::uint32_t extent = chunk != 0 ? chunk : std::max({d.x, d.y, d.z});
    std::uint32_t p2 = 1;
    while (p2 < extent) {
        p2 *= 2;
    }
    std::vector<std::int64_t> steps;
    for (std::int64_t s = p2 / 2; s >= 1; s /= 2) {
        steps.push_back(s);
    }
    if (extra == 2) {
        steps.push_back(2);
    }
    if (extra >= 1) {
        steps.push_back(1);
    }
    for (const std::int64_t s : steps) {
        for (std::int64_t z = 0; z < Z; ++z) {
            for (std::int64_t y = 0; y < Y; ++y) {
                for (std::int64_t x = 0; x < X; ++x) {
                    const auto [x0, x1] = bounds(x, X);
                    const auto [y0, y1] = bounds(y, Y);
                    const auto [z0, z1] = bounds(z, Z);
                    std::uint32_t best = none;
                    std::int64_t best_d = 0;
                    for (std::int64_t k = -1; k <= 1; ++k) {
                        for (std::int64_t j = -1; j <= 1; ++j) {
                            for (std::int64_t i = -1; i <= 1; ++i) {
                                const std::int64_t qx = x + i * s, qy = y + j * s, qz = z + k * s;
                                if (qx < x0 || qx >= x1 || qy < y0 || qy >= y1 || qz < z0 ||
                                    qz >= z1) {
                                    continue;
                                }
                                const std::uint32_t c =
                                    seed[static_cast<std::size_t>((qz * Y + qy) * X + qx)];
                                if (c == none) {
                                    continue;
                                }
                                const std::int64_t cd = l1(x, y, z, c);
                                if (best == none || cd < best_d || (cd == best_d && c < best)) {
                                    best = c;
                                    best_d = cd;
                                }
                            }
                        }
                    }
                    next[static_cast<std::size_t>((z * Y + y) * X + x)] = best;
                }
            }
        }
        seed.swap(next);
    }
    std::vector<std::uint32_t> out(w.size());
    for (std::int64_t z = 0; z < Z; ++z) {
        for (std::int64_t y = 0; y < Y; ++y) {
            for (std::int64_t x = 0; x < X; ++x) {
                const std::size_t i = static_cast<std::size_t>((z * Y + y) * X + x);
                std::int64_t v = seed[i] == none ? kInfinite : l1(x, y, z, seed[i]);
                if (chunk != 0) {
                    const auto [x0, x1] = bounds(x, X);
                    const auto [y0, y1] = bounds(y, Y);
                    const auto [z0, z1] = bounds(z, Z);
                    v = std::min({v, x - x0 + 1, x1 - x, y - y0 + 1, y1 - y, z - z0 + 1, z1 - z});
                }
                out[i] = static_cast<std::uint32_t>(v);
            }
        }
    }
    return out;
}

TEST(Classic, JfaEqualsIndependentCpuJfaAndNeverUnderestimates) {
    std::mt19937_64 rng(99);
    const double densities[] = {0.0005, 0.003, 0.02, 0.1};
    for (int trial = 0; trial < 24; ++trial) {
        const Dims d{static_cast<std::uint32_t>(2 + rng() % 34),
                     static_cast<std::uint32_t>(2 + rng() % 34),
                     static_cast<std::uint32_t>(2 + rng() % 34)};
        const World w = random_world(rng, d, densities[static_cast<std::size_t>(trial) % 4]);
        const std::uint32_t chunk = trial % 3 == 0 ? 0 : chunk_for(d, 16);
        const auto exact =
            chunk == 0 ? reference_manhattan(w) : reference_manhattan_chunked(w, chunk);
        for (std::uint32_t extra = 0; extra <= 2; ++extra) {
            const auto jfa = cpu_jfa(w, chunk, extra);
            for (std::size_t i = 0; i < jfa.size(); ++i) {
                ASSERT_GE(jfa[i], exact[i])
                    << "CPU JFA under-estimates: it must report real solids";
            }
            for (Algorithm a : kJfa) {
                auto o = options(a, Format::u32, chunk, d);
                o.jfa_extra = extra;
                expect_matches(w, Palette(), o, jfa, "vs CPU JFA");
            }
        }
        if (HasFailure()) {
            return;
        }
    }
}

TEST(Classic, LodIsExactInsideTheFocusAndJfaOutside) {
    const World w = scene_floor_spheres(Dims{64, 48, 40}, 11, 24);
    const Dims d = w.dims();
    ocl::GeneratorOptions o;
    o.algorithm = Algorithm::lod;
    o.format = Format::u32;
    o.chunk = 16;
    o.focus = Focus{{1, 1, 1}, 0};
    o = ocl::resolve_options(o, d);
    const auto exact = reference_manhattan_chunked(w, 16);
    const auto jfa = cpu_jfa(w, 16, 0);
    const auto got = ocl::generate(pocl(), w, Palette(), o).bytes;
    std::size_t inside = 0;
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const std::size_t i = d.index(x, y, z);
                const bool in_focus = x / 16 == 1 && y / 16 == 1 && z / 16 == 1;
                inside += in_focus ? 1 : 0;
                ASSERT_EQ(decode_distance(got, Format::u32, i), in_focus ? exact[i] : jfa[i])
                    << "(" << x << "," << y << "," << z << ")";
            }
        }
    }
    EXPECT_EQ(inside, 16u * 16 * 16);
    // monolithic with the same focus gives the same field.
    o.algorithm = Algorithm::monolithic;
    EXPECT_TRUE(ocl::generate(pocl(), w, Palette(), o).bytes == got);
}

TEST(Classic, FimReportsItsPasses) {
    World w(Dims{40, 8, 8});
    w.set(0, 0, 0, 1);
    const auto max_distance = 39u + 7 + 7;
    for (Algorithm a : {Algorithm::fim, Algorithm::fim_host}) {
        auto job = ocl::make_generator(pocl(), w, Palette(), options(a, Format::u16, 0, w.dims()));
        job->run();
        EXPECT_GE(job->iterations(), 1u) << ocl::to_string(a);
        EXPECT_LE(job->iterations(), max_distance) << ocl::to_string(a);
    }
    // JFA finds every distance of a single seed, so FIM after it changes nothing.
    auto hybrid = ocl::make_generator(pocl(), w, Palette(),
                                      options(Algorithm::jfa_fim, Format::u16, 0, w.dims()));
    hybrid->run();
    EXPECT_EQ(hybrid->iterations(), 0u);
}

TEST(Classic, RepeatedRunsAreBitIdentical) {
    const World w = scene_terrain(Dims{48, 40, 36}, 5);
    for (const std::string& name : ocl::algorithm_names()) {
        const Algorithm a = ocl::parse_algorithm(name);
        auto o = options(a, Format::packed32, 0, w.dims(), false);
        if (a == Algorithm::brute_chunked || a == Algorithm::lod || a == Algorithm::monolithic) {
            o = options(a, Format::packed32, 8, w.dims(), false);
        }
        auto job = ocl::make_generator(pocl(), w, Palette(), o);
        job->run();
        const auto first = job->read();
        for (int i = 0; i < 3; ++i) {
            job->run();
            EXPECT_TRUE(job->read() == first) << name;
        }
    }
}

TEST(Classic, OptionsAreChecked) {
    const Dims d{32, 16, 64};
    auto with = [&](Algorithm a, std::uint32_t chunk) {
        ocl::GeneratorOptions o;
        o.algorithm = a;
        o.chunk = chunk;
        return o;
    };
    EXPECT_THROW(ocl::resolve_options(with(Algorithm::fim, 12), d), InputError);
    EXPECT_THROW(ocl::resolve_options(with(Algorithm::fim, 32), d), InputError);  // y is 16
    EXPECT_THROW(ocl::resolve_options(with(Algorithm::exact, 8), d), InputError);
    EXPECT_EQ(ocl::resolve_options(with(Algorithm::lod, 0), d).chunk, ocl::kDefaultChunk);
    const auto lod = ocl::resolve_options(with(Algorithm::lod, 8), d);
    ASSERT_TRUE(lod.focus.has_value());
    EXPECT_EQ(lod.focus->centre, (Int3{2, 1, 4}));
    auto focus = with(Algorithm::monolithic, 8);
    focus.focus = Focus{{4, 0, 0}, 1};
    EXPECT_THROW(ocl::resolve_options(focus, d), InputError);
    focus.algorithm = Algorithm::fim;
    focus.focus = Focus{{0, 0, 0}, 1};
    EXPECT_THROW(ocl::resolve_options(focus, d), InputError);
    auto extra = with(Algorithm::jfa, 0);
    extra.jfa_extra = 3;
    EXPECT_THROW(ocl::resolve_options(extra, d), InputError);
    extra.algorithm = Algorithm::fim;
    extra.jfa_extra = 1;
    EXPECT_THROW(ocl::resolve_options(extra, d), InputError);
    EXPECT_THROW(ocl::parse_algorithm("jfa2"), InputError);
    for (const std::string& name : ocl::algorithm_names()) {
        EXPECT_EQ(ocl::to_string(ocl::parse_algorithm(name)), name);
    }
}

TEST(Classic, BruteForceRefusesGridsThatWouldTakeMinutes) {
    const World w(Dims{256, 256, 256});
    try {
        ocl::make_generator(pocl(), w, Palette(),
                            options(Algorithm::brute, Format::u8, 0, w.dims()));
        FAIL() << "brute force on 256^3 accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("--algorithm exact"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace voxfield
