#pragma once
// What the files of vk/'s runtime share privately (not installed): the instance every
// Context and device listing creates.
#include <memory>
#include <string>
#include <vector>

#include "voxfield/vk/context.hpp"

namespace voxfield::vk {

// An instance with `extensions` (none: headless compute only), with validation when a log is
// given (silencing lavapipe's non-conformance warning, which a library must not print).
Instance create_instance(std::shared_ptr<ValidationLog> validation,
                         const std::vector<std::string>& extensions = {});

}  // namespace voxfield::vk
