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
constexpr auto kKeepAlive = std::chrono::seconds(10);

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
  server_->Get("/", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-cache");
    res.set_content(page_html_, "text/html; charset=utf-8");
  });
  server_->Get("/state", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-cache");
    res.set_content(state_.json(), "application/json");
  });
  server_->Get("/events", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-cache");
    res.set_header("X-Accel-Buffering", "no");  // a proxy in front must not hold the stream back
    // One provider per connection: it is called again for as long as it
    // returns true and the peer reads.
    auto last_sent = std::make_shared<std::uint64_t>(0);
    auto last_write = std::make_shared<std::chrono::steady_clock::time_point>(std::chrono::steady_clock::now());
    res.set_chunked_content_provider("text/event-stream", [this, last_sent, last_write](std::size_t, httplib::DataSink& sink) {
      if (stopping_.load()) return false;
      const std::uint64_t now_version = state_.waitNewer(*last_sent, std::chrono::milliseconds(500));
      if (stopping_.load()) return false;
      const auto now = std::chrono::steady_clock::now();
      std::string event;
      if (now_version > *last_sent) {
        event = "data: " + state_.json() + "\n\n";
        *last_sent = now_version;
      } else if (now - *last_write >= kKeepAlive) {
        event = ": keep-alive\n\n";
      }
      if (!event.empty()) {
        if (!sink.write(event.data(), event.size())) return false;
        *last_write = now;
        std::this_thread::sleep_for(kMinEventGap);
      }
      return true;
    });
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

void ViewServer::run() { server_->listen_after_bind(); }

void ViewServer::stop() {
  stopping_.store(true);
  server_->stop();
}

}  // namespace rilo::tool
