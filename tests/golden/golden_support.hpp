// Helpers of the end-to-end tests: run the built `ptda` binary with std::system (outputs captured in
// files under PTDA_TEST_TMP), read the files back, parse monitor JSONL.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "ptda/cli/jsonl.hpp"

namespace ptda::golden {

namespace fs = std::filesystem;

inline fs::path source_dir() {
  return fs::path(PTDA_SOURCE_DIR);
}

/// A fresh scratch directory PTDA_TEST_TMP/golden/<name> (emptied).
inline fs::path scratch_dir(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  const fs::path base = env != nullptr ? fs::path(env) : fs::temp_directory_path() / "ptda-test-tmp";
  const fs::path dir = base / "golden" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

inline std::string read_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

inline std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (const char c : s) {
    if (c == '\'') {
      out += "'\\''";
    } else {
      out.push_back(c);
    }
  }
  return out + "'";
}

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

/// Runs the shell command `cmd` (already quoted) with stdout/stderr captured into dir/<tag>.out/.err
/// and stdin from /dev/null.
inline RunResult run_captured(std::string cmd, const fs::path& dir, const std::string& tag) {
  const fs::path out = dir / (tag + ".out");
  const fs::path err = dir / (tag + ".err");
  cmd += " >" + shell_quote(out.string()) + " 2>" + shell_quote(err.string()) + " </dev/null";
  const int status = std::system(cmd.c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_file(out);
  r.err = read_file(err);
  return r;
}

/// Runs `ptda args...` with stdout/stderr captured into dir/<tag>.out/.err.
inline RunResult run_ptda(const std::vector<std::string>& args, const fs::path& dir, const std::string& tag) {
  std::string cmd = shell_quote(PTDA_CLI_BINARY);
  for (const auto& a : args) cmd += " " + shell_quote(a);
  return run_captured(std::move(cmd), dir, tag);
}

/// One parsed JSONL object per line; fails the test on a malformed line.
inline std::vector<cli::JsonValue> read_jsonl(const fs::path& p) {
  std::vector<cli::JsonValue> rows;
  std::ifstream f(p);
  std::string line;
  int n = 0;
  while (std::getline(f, line)) {
    ++n;
    rows.push_back(cli::parse_json(line, p.string() + ":" + std::to_string(n)));
  }
  return rows;
}

}  // namespace ptda::golden
