// JSON lines on stdout for the C++ test programs driven by tests/ros (participant_process,
// client_process, rclcpp/*): strings and lists of names as JSON, and
// {"event": EVENT, FIELDS} lines flushed at once (thread-safe).
#pragma once

#include <cstdio>
#include <mutex>
#include <string>
#include <vector>

namespace contextros::test_output {

inline std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", c);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

inline std::string json_list(const std::vector<std::string>& names) {
  std::string out = "[";
  for (std::size_t i = 0; i < names.size(); ++i) {
    out += (i ? ", " : "") + json_string(names[i]);
  }
  return out + "]";
}

// `fields`: already JSON (`"key": value, ...`), or empty.
inline void emit(const std::string& event, const std::string& fields = "") {
  static std::mutex output;
  std::lock_guard<std::mutex> lock(output);
  std::printf("{\"event\": %s%s%s}\n", json_string(event).c_str(), fields.empty() ? "" : ", ",
              fields.c_str());
  std::fflush(stdout);
}

}  // namespace contextros::test_output
