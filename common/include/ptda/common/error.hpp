// Errors for configure-time and offline code. Real-time paths never throw: they return codes and count.
#pragma once

#include <stdexcept>
#include <string>

namespace ptda {

/// An error a person can act on: says what is wrong and where (file, line, column when known).
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
  /// Formats "<where>:<line>:<column>: <what>" (line/column omitted when 0).
  Error(const std::string& where, long line, long column, const std::string& what)
      : std::runtime_error(format(where, line, column, what)) {}

 private:
  static std::string format(const std::string& where, long line, long column, const std::string& what) {
    std::string s = where;
    if (line > 0) s += ":" + std::to_string(line);
    if (column > 0) s += ":" + std::to_string(column);
    return s + ": " + what;
  }
};

}  // namespace ptda
