// `view --script`: parsing and playing scripted input (see view_script.hpp).
#include "view_script.hpp"

#include <GLFW/glfw3.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <sstream>

#include "voxfield/cl/generator.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/scenes.hpp"

namespace voxfield::cli {
namespace {

std::string upper(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
    return s;
}

int key_code(const std::string& name) {
    const std::string n = upper(name);
    if (n.size() == 1 && n[0] >= 'A' && n[0] <= 'Z') {
        return GLFW_KEY_A + (n[0] - 'A');
    }
    if (n.size() == 1 && n[0] >= '0' && n[0] <= '9') {
        return GLFW_KEY_0 + (n[0] - '0');
    }
    if (n.size() >= 2 && n[0] == 'F') {
        int f = 0;
        const auto [end, ec] = std::from_chars(n.data() + 1, n.data() + n.size(), f);
        if (ec == std::errc() && end == n.data() + n.size() && f >= 1 && f <= 12) {
            return GLFW_KEY_F1 + (f - 1);
        }
    }
    static const std::map<std::string, int> named = {{"ESC", GLFW_KEY_ESCAPE},
                                                     {"TAB", GLFW_KEY_TAB},
                                                     {"SPACE", GLFW_KEY_SPACE},
                                                     {"ENTER", GLFW_KEY_ENTER},
                                                     {"UP", GLFW_KEY_UP},
                                                     {"DOWN", GLFW_KEY_DOWN},
                                                     {"LEFT", GLFW_KEY_LEFT},
                                                     {"RIGHT", GLFW_KEY_RIGHT},
                                                     {"LSHIFT", GLFW_KEY_LEFT_SHIFT},
                                                     {"LCTRL", GLFW_KEY_LEFT_CONTROL},
                                                     {"LALT", GLFW_KEY_LEFT_ALT},
                                                     {"RCTRL", GLFW_KEY_RIGHT_CONTROL}};
    const auto it = named.find(n);
    return it == named.end() ? -1 : it->second;
}

int button_code(const std::string& name) {
    if (name == "left") {
        return GLFW_MOUSE_BUTTON_LEFT;
    }
    if (name == "right") {
        return GLFW_MOUSE_BUTTON_RIGHT;
    }
    return -1;
}

bool parse_number(const std::string& s, double& out) {
    std::istringstream in(s);
    in >> out;
    return !in.fail() && in.eof();
}

void check_select(const std::string& what, const std::string& value, const std::string& where) {
    const auto one_of = [&](const std::vector<std::string>& names) {
        if (std::find(names.begin(), names.end(), value) == names.end()) {
            std::string list;
            for (const auto& n : names) {
                list += (list.empty() ? "" : ", ") + n;
            }
            throw InputError(where + ": no " + what + " '" + value + "' (one of: " + list + ")");
        }
    };
    if (what == "algorithm") {
        one_of(ocl::algorithm_names());
    } else if (what == "metric") {
        one_of(metric_names());
    } else if (what == "scene") {
        one_of(scene_names());
    } else if (what == "shading") {
        one_of({"flat", "lit"});
    } else if (what == "colour") {
        double c = 0;
        if (!parse_number(value, c) || c < 1 || c > 255 || c != static_cast<int>(c)) {
            throw InputError(where + ": colour '" + value + "' is not 1..255");
        }
    } else {
        throw InputError(where + ": cannot select '" + what +
                         "' (algorithm, metric, scene, shading or colour)");
    }
}

}  // namespace

std::vector<ScriptAction> parse_view_script(const std::string& text) {
    std::vector<ScriptAction> actions;
    std::istringstream lines(text);
    std::string line;
    std::size_t number = 0;
    using Kind = ScriptAction::Kind;
    static const std::map<std::string, Kind> kinds = {
        {"key", Kind::key},     {"down", Kind::down},     {"up", Kind::up},
        {"click", Kind::click}, {"press", Kind::press},   {"release", Kind::release},
        {"mouse", Kind::mouse}, {"scroll", Kind::scroll}, {"select", Kind::select},
        {"save", Kind::save},   {"check", Kind::check},   {"quit", Kind::quit}};
    while (std::getline(lines, line)) {
        ++number;
        if (const auto hash = line.find('#'); hash != std::string::npos) {
            line.resize(hash);
        }
        std::istringstream words(line);
        std::vector<std::string> w;
        for (std::string word; words >> word;) {
            w.push_back(word);
        }
        if (w.empty()) {
            continue;
        }
        const std::string where = "script line " + std::to_string(number);
        ScriptAction a;
        a.line = number;
        double frame = 0;
        if (!parse_number(w[0], frame) || frame < 0 ||
            frame != static_cast<double>(static_cast<std::uint64_t>(frame))) {
            throw InputError(where + ": '" + w[0] + "' is not a frame number");
        }
        a.frame = static_cast<std::uint64_t>(frame);
        if (w.size() < 2 || !kinds.contains(w[1])) {
            throw InputError(where +
                             ": expected an action (key, down, up, click, press, "
                             "release, mouse, scroll, select, save, check, quit)");
        }
        a.kind = kinds.at(w[1]);
        const auto need = [&](std::size_t n, const char* usage) {
            if (w.size() != n + 2) {
                throw InputError(where + ": usage: FRAME " + w[1] + " " + usage);
            }
        };
        switch (a.kind) {
            case Kind::key:
            case Kind::down:
            case Kind::up: {
                need(1, "NAME");
                std::string name = w[2];
                if (a.kind == Kind::key && upper(name).rfind("CTRL+", 0) == 0) {
                    a.ctrl = true;
                    name = name.substr(5);
                }
                a.code = key_code(name);
                if (a.code < 0) {
                    throw InputError(where + ": unknown key '" + w[2] + "'");
                }
                break;
            }
            case Kind::click:
            case Kind::press:
            case Kind::release:
                need(1, "left|right");
                a.code = button_code(w[2]);
                if (a.code < 0) {
                    throw InputError(where + ": unknown mouse button '" + w[2] +
                                     "' (left or right)");
                }
                break;
            case Kind::mouse:
                need(2, "X Y");
                if (!parse_number(w[2], a.x) || !parse_number(w[3], a.y)) {
                    throw InputError(where + ": mouse position '" + w[2] + " " + w[3] +
                                     "' is not two numbers");
                }
                break;
            case Kind::scroll:
                need(1, "NOTCHES");
                if (!parse_number(w[2], a.x)) {
                    throw InputError(where + ": '" + w[2] + "' is not a number of notches");
                }
                break;
            case Kind::select:
                need(2, "algorithm|metric|scene|shading|colour VALUE");
                a.what = w[2];
                a.value = w[3];
                check_select(a.what, a.value, where);
                break;
            case Kind::save:
            case Kind::check:
                need(1, "STEM");
                a.value = w[2];
                break;
            case Kind::quit:
                need(0, "");
                break;
        }
        actions.push_back(a);
    }
    return actions;
}

std::vector<ScriptAction> read_view_script(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw InputError("cannot read script " + path.string() + ": " + std::strerror(errno));
    }
    std::ostringstream text;
    text << in.rdbuf();
    return parse_view_script(text.str());
}

ViewScript::ViewScript(std::vector<ScriptAction> actions) {
    for (ScriptAction& a : actions) {
        const std::uint64_t f = a.frame;
        by_frame_.emplace(f, std::move(a));
    }
}

std::vector<ScriptAction> ViewScript::begin_frame(std::uint64_t frame) {
    using Kind = ScriptAction::Kind;
    keys_ = held_keys_;
    buttons_ = held_buttons_;
    scroll_ = 0;
    std::vector<ScriptAction> out;
    const auto [first, last] = by_frame_.equal_range(frame);
    for (auto it = first; it != last; ++it) {
        const ScriptAction& a = it->second;
        switch (a.kind) {
            case Kind::key:
                keys_.insert(a.code);
                if (a.ctrl) {
                    keys_.insert(GLFW_KEY_LEFT_CONTROL);
                }
                break;
            case Kind::down:
                held_keys_.insert(a.code);
                keys_.insert(a.code);
                break;
            case Kind::up:
                held_keys_.erase(a.code);
                keys_.erase(a.code);
                break;
            case Kind::click:
                buttons_.insert(a.code);
                break;
            case Kind::press:
                held_buttons_.insert(a.code);
                buttons_.insert(a.code);
                break;
            case Kind::release:
                held_buttons_.erase(a.code);
                buttons_.erase(a.code);
                break;
            case Kind::mouse:
                has_cursor_ = true;
                cursor_x_ = a.x;
                cursor_y_ = a.y;
                break;
            case Kind::scroll:
                scroll_ += a.x;
                break;
            case Kind::select:
            case Kind::save:
            case Kind::check:
            case Kind::quit:
                break;
        }
        out.push_back(a);
    }
    return out;
}

std::uint64_t ViewScript::end_frame() const {
    return by_frame_.empty() ? 0 : by_frame_.rbegin()->first + 1;
}

}  // namespace voxfield::cli
