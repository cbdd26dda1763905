#include "view_server.h"

#include <httplib.h>
#include <sys/socket.h>

#include <chrono>
#include <stdexcept>
#include <thread>
#include <utility>

namespace rilo::tool {
namespace {

constexpr auto kMinEventGap = std::chrono::milliseconds(100);  // the page redraws at most 10 times a second
/// The picture at least this often without a change: its ages move on, so a
/// page over a service that went silent says so.
constexpr auto kRefresh = std::chrono::seconds(1);
/// Open pages at most: each event stream holds one of the server's threads.
constexpr int kMaxStreams = 16;

}  // namespace

ViewServer::ViewServer(ViewState& state, std::string page_html)
    : state_(state), page_html_(std::move(page_html)), server_(std::make_unique<httplib::Server>()) {
  // httplib's default also sets SO_REUSEPORT: a second `rilo view` on the same
  // port would then bind too and the kernel would split the browsers between
  // the two. SO_REUSEADDR alone restarts after TIME_WAIT and refuses a busy port.
  server_->set_socket_options([](socket_t sock) {
    const int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  // Every open page holds a worker for its stream: room for kMaxStreams and
  // the plain requests beside them; an idle keep-alive connection lets go soon.
  server_->new_task_queue = [] { return new httplib::ThreadPool(kMaxStreams + 8); };
  server_->set_keep_alive_timeout(1);
  server_->Get("/", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-cache");
    res.set_content(page_html_, "text/html; charset=utf-8");
  });
  server_->Get("/state", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-cache");
    res.set_content(state_.json(), "application/json");
  });
  server_->Get("/events", [this](const httplib::Request&, httplib::Response& res) {
    if (streams_.fetch_add(1) >= kMaxStreams) {
      streams_.fetch_sub(1);
      res.status = 503;
      res.set_content("too many open pages (" + std::to_string(kMaxStreams) + ")\n", "text/plain");
      return;
    }
    res.set_header("Cache-Control", "no-cache");
    res.set_header("X-Accel-Buffering", "no");  // a proxy in front must not hold the stream back
    // One provider per connection: it is called again for as long as it
    // returns true and the peer reads. The first call sends the picture as it
    // is (the anchors before any message); then on change, or every kRefresh.
    struct Stream {
      bool started = false;
      std::uint64_t sent_version = 0;
      std::chrono::steady_clock::time_point sent_at;
    };
    auto stream = std::make_shared<Stream>();
    res.set_chunked_content_provider(
        "text/event-stream",
        [this, stream](std::size_t, httplib::DataSink& sink) {
          if (stopping_.load()) return false;
          if (stream->started) state_.waitNewer(stream->sent_version, std::chrono::milliseconds(250));
          if (stopping_.load()) return false;
          const auto now = std::chrono::steady_clock::now();
          const std::uint64_t version = state_.version();
          if (stream->started && version == stream->sent_version && now - stream->sent_at < kRefresh) return true;
          const std::string event = "data: " + state_.json() + "\n\n";
          if (!sink.write(event.data(), event.size())) return false;
          stream->started = true;
          stream->sent_version = version;
          stream->sent_at = now;
          std::this_thread::sleep_for(kMinEventGap);
          return true;
        },
        [this](bool) { streams_.fetch_sub(1); });
  });
}

ViewServer::~ViewServer() { stop(); }

int ViewServer::bind(const std::string& host, int port) {
  const int bound = port == 0 ? server_->bind_to_any_port(host) : (server_->bind_to_port(host, port) ? port : -1);
  if (bound <= 0) {
    throw std::runtime_error("cannot listen on " + host + ":" + std::to_string(port) +
                             " (address in use, or not an address of this machine)");
  }
  return bound;
}

void ViewServer::run() {
  {
    std::lock_guard<std::mutex> lock(run_mutex_);
    if (stopping_.load()) return;
    running_ = true;
  }
  server_->listen_after_bind();
}

void ViewServer::stop() {
  stopping_.store(true);
  {
    std::lock_guard<std::mutex> lock(run_mutex_);
    if (!running_) return;  // run() has not started and now never will
  }
  // httplib's stop() does nothing until the listening loop is up: wait for it
  // (it is a moment after run() began), so run() cannot miss the stop.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (!server_->is_running() && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  server_->stop();
}

}  // namespace rilo::tool
