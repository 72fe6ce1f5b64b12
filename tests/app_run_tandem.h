// Runs the built `tandem` binary (TANDEM_BINARY) the way a user would, for
// the app tests.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace tandem::app_test {

struct RunResult {
  int exit_code;
  std::string output;  // stdout + stderr
};

inline std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s)
    out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Any shell command line; its stdout and stderr together.
inline RunResult run_command(const std::string& cmd_line) {
  const std::string cmd = cmd_line + " 2>&1";
  RunResult r{-1, ""};
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf;
  while (size_t n = fread(buf.data(), 1, buf.size(), pipe))
    r.output.append(buf.data(), n);
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

#ifdef TANDEM_BINARY  // test binaries that run `tandem` itself
// `env` ("NAME=value ..." or empty) is set for this run only; a non-empty
// `cwd` is its working directory.
inline RunResult run_tandem_with_env(const std::string& env, const std::string& args,
                                     const std::string& cwd = "") {
  return run_command((cwd.empty() ? "" : "cd " + shell_quote(cwd) + " && ") +
                     (env.empty() ? "" : "env " + env + " ") + shell_quote(TANDEM_BINARY) + " " +
                     args);
}

inline RunResult run_tandem(const std::string& args) {
  return run_tandem_with_env("", args);
}

inline RunResult run_tandem_in(const std::string& cwd, const std::string& args) {
  return run_tandem_with_env("", args, cwd);
}

#endif

}  // namespace tandem::app_test
