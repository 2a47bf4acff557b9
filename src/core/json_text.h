#pragma once
// JSON text in and out. nlohmann's parser and serializer are large templates: every file that called parse() or
// dump() itself compiled and optimised its own copy (4-10 s per file, most of a sanitizer build's JSON cost).
// They are instantiated once, in json_text.cpp; everything else reads and writes JSON text through these.
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

namespace egopd {

// Parse errors are nlohmann::json::parse_error, as from nlohmann::json::parse (callers name the file).
nlohmann::json parse_json(std::string_view text);
nlohmann::json parse_json(std::istream& in);
// With a callback on every parse event (duplicate-key checks of the safetensors headers).
nlohmann::json parse_json(std::string_view text, const nlohmann::json::parser_callback_t& callback);

// indent < 0: one line. Strings that are not valid UTF-8 throw nlohmann::json::type_error unless
// replace_invalid_utf8 (then U+FFFD).
std::string dump_json(const nlohmann::json& j, int indent = -1, bool replace_invalid_utf8 = false);
std::string dump_json(const nlohmann::ordered_json& j, int indent = -1, bool replace_invalid_utf8 = false);

}  // namespace egopd
