#pragma once
// Random `.sdf.json` parts for the implicit-surface tests (core and kernels): every primitive
// and operator of DESIGN §3, with random materials, inside [-1, 1]^3.
#include <nlohmann/json.hpp>

#include <random>
#include <string>

namespace voxfield::test {

class RandomPart {
  public:
    explicit RandomPart(unsigned seed) : rng_(seed) {}

    nlohmann::json node(int depth) {
        nlohmann::json n;
        const int kind = depth <= 0 ? pick(0, 6) : pick(0, 13);
        switch (kind) {
            case 0:
                n["sphere"] = {{"center", vec(-0.5, 0.5)}, {"radius", real(0.1, 0.6)}};
                break;
            case 1:
                n["box"] = {{"center", vec(-0.5, 0.5)}, {"half_size", vec(0.1, 0.5)}};
                break;
            case 2: {
                const auto s = vec(0.15, 0.5);
                const double m =
                    std::min({s[0].get<double>(), s[1].get<double>(), s[2].get<double>()});
                n["round_box"] = {
                    {"center", vec(-0.5, 0.5)}, {"half_size", s}, {"radius", real(0.02, m)}};
                break;
            }
            case 3:
                n["cylinder"] = {{"center", vec(-0.5, 0.5)},
                                 {"radius", real(0.1, 0.5)},
                                 {"half_height", real(0.1, 0.5)}};
                break;
            case 4:
                n["torus"] = {{"center", vec(-0.4, 0.4)},
                              {"major", real(0.2, 0.5)},
                              {"minor", real(0.05, 0.2)}};
                break;
            case 5:
                n["capsule"] = {
                    {"a", vec(-0.6, 0.6)}, {"b", vec(-0.6, 0.6)}, {"radius", real(0.05, 0.3)}};
                break;
            case 6:
                n["plane"] = {{"normal", vec(-1, 1)}, {"offset", real(-0.5, 0.5)}};
                break;
            case 7:
            case 8: {
                nlohmann::json kids = nlohmann::json::array();
                for (int i = pick(1, 3); i > 0; --i) {
                    kids.push_back(node(depth - 1));
                }
                n[kind == 7 ? "union" : "intersection"] = kids;
                break;
            }
            case 9:
                n["difference"] = {node(depth - 1), node(depth - 1)};
                break;
            case 10:
                n["smooth_union"] = {{"k", real(0.02, 0.4)},
                                     {"of", {node(depth - 1), node(depth - 1)}}};
                break;
            case 11:
                n["smooth_difference"] = {{"k", real(0.02, 0.4)},
                                          {"of", {node(depth - 1), node(depth - 1)}}};
                break;
            case 12:
                n["transform"] = {{"translate", vec(-0.3, 0.3)},
                                  {"rotate_deg", vec(-180, 180)},
                                  {"scale", real(0.5, 1.5)},
                                  {"of", node(depth - 1)}};
                break;
            default:
                n["shell"] = {{"thickness", real(0.02, 0.1)}, {"of", node(depth - 1)}};
                break;
        }
        if (pick(0, 3) == 0) {
            n["material"] = pick(1, 255);
        }
        return n;
    }

    // A whole part over [-1, 1]^3 at voxel size h.
    std::string part(int depth, double h) {
        nlohmann::json doc = {{"version", 1},
                              {"voxel_size", h},
                              {"bounds", {{-1, -1, -1}, {1, 1, 1}}},
                              {"shape", node(depth)}};
        return doc.dump();
    }

    double real(double lo, double hi) {
        return std::uniform_real_distribution<double>(lo, hi)(rng_);
    }
    int pick(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }

  private:
    nlohmann::json vec(double lo, double hi) { return {real(lo, hi), real(lo, hi), real(lo, hi)}; }

    std::mt19937 rng_;
};

}  // namespace voxfield::test
