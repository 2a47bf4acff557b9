#pragma once
// UTF-8 validity of text that ends up in JSON outputs (prompts, paths): checked before any work, so an invalid byte
// sequence is one clear error instead of a JSON library exception after the whole computation.
#include <string>

namespace egopd {

// Well-formed UTF-8 (no overlong forms, no surrogates, at most U+10FFFF).
bool is_valid_utf8(const std::string& s);

}  // namespace egopd
