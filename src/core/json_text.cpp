#include "core/json_text.h"

#include <istream>

namespace egopd {

nlohmann::json parse_json(std::string_view text) { return nlohmann::json::parse(text.begin(), text.end()); }

nlohmann::json parse_json(std::istream& in) { return nlohmann::json::parse(in); }

nlohmann::json parse_json(std::string_view text, const nlohmann::json::parser_callback_t& callback) {
  return nlohmann::json::parse(text.begin(), text.end(), callback);
}

namespace {
template <class Json>
std::string dump(const Json& j, int indent, bool replace_invalid_utf8) {
  return j.dump(indent, ' ', false,
                replace_invalid_utf8 ? nlohmann::json::error_handler_t::replace : nlohmann::json::error_handler_t::strict);
}
}  // namespace

std::string dump_json(const nlohmann::json& j, int indent, bool replace_invalid_utf8) {
  return dump(j, indent, replace_invalid_utf8);
}

std::string dump_json(const nlohmann::ordered_json& j, int indent, bool replace_invalid_utf8) {
  return dump(j, indent, replace_invalid_utf8);
}

}  // namespace egopd
