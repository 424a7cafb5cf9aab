// The shipped markloop.conf and the keys' tables of docs/configuration.md,
// written from the settings table (settings.hpp) by markloop-settings and
// compared with the committed files by tests/ecu/test_settings.cpp.
#pragma once

#include <string>
#include <string_view>

#include "app/common/result.hpp"

namespace markloop::ecu {

// How to rewrite both files from the source tree's root.
inline constexpr std::string_view kRegenerateCommand = "build/host/bin/markloop-settings --write .";

// The lines around the generated part of docs/configuration.md.
inline constexpr std::string_view kReferenceBegin =
    "<!-- Generated from app/ecu/settings.cpp by markloop-settings --write: edit the table there. -->\n";
inline constexpr std::string_view kReferenceEnd = "<!-- End of the generated part. -->\n";

// The text of app/ecu/markloop.conf.
std::string reference_conf();

// The keys' tables, one section each, markers included.
std::string reference_docs();

// `document` with the part between the markers (markers included) replaced
// by reference_docs(), or what is wrong (missing markers).
Result<std::string> with_reference_docs(std::string_view document);

}  // namespace markloop::ecu
