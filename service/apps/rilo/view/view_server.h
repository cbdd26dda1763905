#pragma once
// The HTTP side of `rilo view` (cpp-httplib, Debian's libcpp-httplib-dev):
//   GET /         the page (view_page.html, one file, no build step)
//   GET /state    the current picture as JSON (ViewState::json)
//   GET /events   server-sent events: the picture at once, then again on every
//                 change (at most every 100 ms) and at least every second (its
//                 ages move on: a silent service shows); 16 pages at most (503)
// Bound to one address (127.0.0.1 by default: the page has no access control).
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "view_state.h"

namespace httplib {
class Server;
}

namespace rilo::tool {

class ViewServer {
 public:
  ViewServer(ViewState& state, std::string page_html);
  ~ViewServer();
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;

  /// Binds `host`:`port` (0: any free port); returns the port, throws
  /// std::runtime_error naming the address when it cannot bind.
  int bind(const std::string& host, int port);
  /// Serves until stop(); call after bind(). Returns at once after a stop().
  void run();
  /// Ends run() and every open event stream (any thread; before run() too).
  void stop();

 private:
  ViewState& state_;
  std::string page_html_;
  std::unique_ptr<httplib::Server> server_;
  std::atomic<bool> stopping_{false};
  std::atomic<int> streams_{0};  ///< open event streams
  std::mutex run_mutex_;         ///< run() starting vs stop()
  bool running_ = false;
};

/// Stops `server` and joins the thread running it when the scope ends,
/// however it ends.
struct ServerThread {
  ViewServer& server;
  std::thread& thread;
  ~ServerThread() {
    server.stop();
    if (thread.joinable()) thread.join();
  }
};

}  // namespace rilo::tool
