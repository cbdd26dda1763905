#pragma once
// A headless Chromium driven over the DevTools protocol on a pipe
// (--remote-debugging-pipe: the browser reads NUL-terminated JSON commands on
// its fd 3 and writes replies and events on its fd 4). Enough of the protocol
// for the browser tests: open a page, evaluate an expression, take a screenshot.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace rilo::testing {

/// Debian's chromium, or "" when none is installed.
inline std::string findChromium() {
  for (const char* path : {"/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"}) {
    if (::access(path, X_OK) == 0) return path;
  }
  return {};
}

class HeadlessChromium {
 public:
  /// Starts the browser with its profile in `profile_dir` (fresh per test).
  HeadlessChromium(const std::string& exe, const std::filesystem::path& profile_dir) {
    // A browser that died must fail the test with a message, not kill it with SIGPIPE.
    ::signal(SIGPIPE, SIG_IGN);
    int to_browser[2], from_browser[2];
    // Close-on-exec: the browser keeps only the ends dup2'd onto its fds 3 and 4.
    if (::pipe2(to_browser, O_CLOEXEC) != 0 || ::pipe2(from_browser, O_CLOEXEC) != 0) {
      throw std::runtime_error("pipe2 failed");
    }
    const std::string profile = "--user-data-dir=" + profile_dir.string();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      // The browser's fd 3 reads our commands, its fd 4 writes to us. Copied
      // above 10 first: a pipe end may itself be fd 3 or 4 (dup2 onto itself
      // would keep its close-on-exec flag, and the first dup2 could overwrite
      // the second end); the copies carry no close-on-exec flag.
      const int commands = ::fcntl(to_browser[0], F_DUPFD, 10);
      const int replies = ::fcntl(from_browser[1], F_DUPFD, 10);
      if (commands < 0 || replies < 0 || ::dup2(commands, 3) < 0 || ::dup2(replies, 4) < 0) ::_exit(126);
      ::close(commands);
      ::close(replies);
      const int null_fd = ::open("/dev/null", O_WRONLY);
      ::dup2(null_fd, STDOUT_FILENO);
      ::dup2(null_fd, STDERR_FILENO);  // DBus complaints of a machine without a session bus
      // root in a container: no sandbox; no GPU here.
      ::execl(exe.c_str(), exe.c_str(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
              "--remote-debugging-pipe", profile.c_str(), "--window-size=1280,800", "about:blank",
              static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(to_browser[0]);
    ::close(from_browser[1]);
    write_fd_ = to_browser[1];
    read_fd_ = from_browser[0];
  }
  ~HeadlessChromium() {
    if (pid_ <= 0) return;
    try {
      send("Browser.close", nlohmann::json::object(), "");
    } catch (...) {
    }
    ::close(write_fd_);
    for (int i = 0; i < 100; ++i) {
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) {
        ::close(read_fd_);
        return;
      }
      ::usleep(50'000);
    }
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    ::close(read_fd_);
  }
  HeadlessChromium(const HeadlessChromium&) = delete;
  HeadlessChromium& operator=(const HeadlessChromium&) = delete;

  /// Sends a command and returns its "result"; throws on a protocol error.
  nlohmann::json call(const std::string& method, const nlohmann::json& params, const std::string& session = "") {
    const int id = send(method, params, session);
    for (;;) {
      nlohmann::json message = next();
      if (!message.contains("id") || message["id"] != id) continue;  // an event, or another reply
      if (message.contains("error")) throw std::runtime_error(method + ": " + message["error"].dump());
      return message["result"];
    }
  }

  /// Opens `url` in a new page of width x height; returns the session to talk to it.
  std::string open(const std::string& url, int width, int height) {
    const nlohmann::json target =
        call("Target.createTarget", {{"url", url}, {"width", width}, {"height", height}, {"newWindow", true}});
    const nlohmann::json attached =
        call("Target.attachToTarget", {{"targetId", target["targetId"]}, {"flatten", true}});
    return attached["sessionId"];
  }

  /// The value of a JavaScript expression in the page (returned by value).
  nlohmann::json evaluate(const std::string& session, const std::string& expression) {
    const nlohmann::json r = call("Runtime.evaluate", {{"expression", expression}, {"returnByValue", true}}, session);
    if (r.contains("exceptionDetails")) throw std::runtime_error("page threw: " + r["exceptionDetails"].dump());
    return r["result"].value("value", nlohmann::json());
  }

  /// A PNG of the page as it is drawn now.
  std::string screenshotPng(const std::string& session) {
    return decodeBase64(call("Page.captureScreenshot", {{"format", "png"}}, session)["data"].get<std::string>());
  }

 private:
  int send(const std::string& method, const nlohmann::json& params, const std::string& session) {
    nlohmann::json message{{"id", ++last_id_}, {"method", method}, {"params", params}};
    if (!session.empty()) message["sessionId"] = session;
    std::string text = message.dump();
    text.push_back('\0');
    for (std::size_t done = 0; done < text.size();) {
      const ssize_t n = ::write(write_fd_, text.data() + done, text.size() - done);
      if (n <= 0) throw std::runtime_error("the browser closed its command pipe");
      done += static_cast<std::size_t>(n);
    }
    return last_id_;
  }

  nlohmann::json next() {
    for (;;) {
      const std::size_t end = buffer_.find('\0');
      if (end != std::string::npos) {
        const std::string text = buffer_.substr(0, end);
        buffer_.erase(0, end + 1);
        return nlohmann::json::parse(text);
      }
      pollfd ready{read_fd_, POLLIN, 0};
      if (::poll(&ready, 1, 60'000) <= 0) throw std::runtime_error("the browser did not answer within 60 s");
      char chunk[65536];
      const ssize_t n = ::read(read_fd_, chunk, sizeof chunk);
      if (n <= 0) throw std::runtime_error("the browser closed its reply pipe (crashed or exited)");
      buffer_.append(chunk, static_cast<std::size_t>(n));
    }
  }

  static std::string decodeBase64(const std::string& text) {
    std::string out;
    unsigned value = 0;
    int bits = 0;
    for (const char c : text) {
      int digit = -1;
      if (c >= 'A' && c <= 'Z') digit = c - 'A';
      if (c >= 'a' && c <= 'z') digit = c - 'a' + 26;
      if (c >= '0' && c <= '9') digit = c - '0' + 52;
      if (c == '+') digit = 62;
      if (c == '/') digit = 63;
      if (digit < 0) continue;  // '=' padding
      value = (value << 6) | static_cast<unsigned>(digit);
      bits += 6;
      if (bits >= 8) {
        bits -= 8;
        out.push_back(static_cast<char>((value >> bits) & 0xFF));
      }
    }
    return out;
  }

  pid_t pid_ = -1;
  int write_fd_ = -1;
  int read_fd_ = -1;
  int last_id_ = 0;
  std::string buffer_;
};

}  // namespace rilo::testing
