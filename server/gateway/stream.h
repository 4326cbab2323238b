// A connection's byte stream for the HTTP door: plain TCP or TLS over it, one type for both.
#pragma once

#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/ssl.hpp>

#include <chrono>
#include <memory>
#include <optional>
#include <string>

namespace hdeform::gateway {

struct GatewayOptions;

namespace asio = boost::asio;
namespace beast = boost::beast;
using tcp = asio::ip::tcp;
using std::chrono::milliseconds;

// A connection's byte stream: plain TCP, or TLS over TCP. Either way one beast::tcp_stream
// owns the socket and carries the deadlines (expires_after), so the rest of the gateway is the
// same for both. Like tcp_stream it is not thread-safe: use it on its strand only.
class Stream {
 public:
  using executor_type = beast::tcp_stream::executor_type;

  Stream(tcp::socket socket, asio::ssl::context* tls) {
    if (tls) {
      tls_.emplace(std::move(socket), *tls);
    } else {
      plain_.emplace(std::move(socket));
    }
  }
  bool is_tls() const { return tls_.has_value(); }
  beast::tcp_stream& tcp_layer() { return tls_ ? tls_->next_layer() : *plain_; }
  executor_type get_executor() { return tcp_layer().get_executor(); }
  tcp::socket& socket() { return tcp_layer().socket(); }
  void expires_after(milliseconds timeout) { tcp_layer().expires_after(timeout); }
  void close() { tcp_layer().close(); }  // also cancels its operations; no TLS close_notify

  template <class Handler>
  void async_handshake(Handler&& handler) {
    tls_->async_handshake(asio::ssl::stream_base::server, std::forward<Handler>(handler));
  }
  template <class MutableBuffers, class Token>
  auto async_read_some(const MutableBuffers& buffers, Token&& token) {
    return asio::async_initiate<Token, void(beast::error_code, std::size_t)>(
        [this](auto handler, const MutableBuffers& b) {
          if (tls_) {
            tls_->async_read_some(b, std::move(handler));
          } else {
            plain_->async_read_some(b, std::move(handler));
          }
        },
        token, buffers);
  }
  template <class ConstBuffers, class Token>
  auto async_write_some(const ConstBuffers& buffers, Token&& token) {
    return asio::async_initiate<Token, void(beast::error_code, std::size_t)>(
        [this](auto handler, const ConstBuffers& b) {
          if (tls_) {
            tls_->async_write_some(b, std::move(handler));
          } else {
            plain_->async_write_some(b, std::move(handler));
          }
        },
        token, buffers);
  }

 private:
  std::optional<beast::tcp_stream> plain_;
  std::optional<beast::ssl_stream<beast::tcp_stream>> tls_;
};


// The server's TLS context (TLS 1.2 at least) from GatewayOptions' PEM files; null when TLS
// is off. Throws std::runtime_error naming a missing or bad file.
std::unique_ptr<asio::ssl::context> make_tls_context(const GatewayOptions& o);

}  // namespace hdeform::gateway
