// Helpers for tests that run the project's binaries as child processes
// (cli_test, mpm_cli_test): a shell command's exit code and stdout, a file's
// bytes, and an rve_server on a free loopback port.
#ifndef RVEHUB_TESTS_SUPPORT_PROCESS_UTIL_H_
#define RVEHUB_TESTS_SUPPORT_PROCESS_UTIL_H_

#include <sys/types.h>

#include <string>
#include <vector>

namespace rvehub::testing_util {

struct CommandResult {
  int exit_code = -1;  // -1 when the command did not exit normally
  std::string out;     // what it wrote to stdout
};

// Runs `command` with /bin/sh (popen) and waits for it. A command that
// cannot be started fails the running test.
CommandResult RunCommand(const std::string& command);

// The bytes of `path`; "" when it cannot be read.
std::string ReadFile(const std::string& path);

// A running rve_server (`server_path`) listening on a free loopback port,
// with one thread, a 5 s drain and `extra_args`; its stderr goes to
// `log_path`. Stopped with SIGTERM (and waited for) by Stop or at
// destruction. The server's stdout pipe is close-on-exec, so that children
// the test starts later do not hold it.
class ServerProcess {
 public:
  ServerProcess(const std::string& server_path, std::string log_path,
                std::vector<std::string> extra_args = {});
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  // SIGTERM (and SIGCONT, should it be stopped) and wait; the exit status
  // (−1 when it did not exit normally).
  int Stop();
  // Sends `signal` (SIGKILL, SIGSTOP, SIGCONT…); after SIGKILL, waits for it
  // to end, after SIGSTOP for it to be stopped (at most 10 s).
  void Signal(int signal);
  pid_t pid() const { return pid_; }

  // "127.0.0.1:PORT" as the server reported it; "" when it did not start.
  const std::string& address() const { return address_; }
  const std::string& log_path() const { return log_path_; }
  std::string Log() const { return ReadFile(log_path_); }

 private:
  pid_t pid_ = -1;
  int exit_code_ = -1;
  std::string address_, log_path_;
};

// A child process running `args` (args[0] the binary), its stdout
// discarded and its stderr in `err_path`, for tests that need one running
// while they do something else. Killed (SIGKILL) and waited for by Kill or
// at destruction.
class ChildProcess {
 public:
  ChildProcess(std::vector<std::string> args, const std::string& err_path);
  ~ChildProcess() { Kill(); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  // Whether it has not ended yet (a child that ended is waited for).
  bool Running();
  void Kill();

 private:
  pid_t pid_ = -1;
};

}  // namespace rvehub::testing_util

#endif  // RVEHUB_TESTS_SUPPORT_PROCESS_UTIL_H_
