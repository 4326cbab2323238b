#include "gateway/http_gateway.h"
#include "gateway/stream.h"

#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>

#include "common/tls_files.h"

namespace hdeform::gateway {

std::unique_ptr<asio::ssl::context> make_tls_context(const GatewayOptions& o) {
  const auto files = service::load_tls_files("hdeform-gateway", o.tls_cert_file, o.tls_key_file,
                                             o.tls_client_ca_file);
  if (!files) return nullptr;
  auto ctx = std::make_unique<asio::ssl::context>(asio::ssl::context::tls_server);
  ctx->set_options(asio::ssl::context::default_workarounds | asio::ssl::context::single_dh_use);
  const auto fail = [](const std::string& why) {
    ERR_clear_error();
    throw std::runtime_error("hdeform-gateway: " + why);
  };
  if (SSL_CTX_set_min_proto_version(ctx->native_handle(), TLS1_2_VERSION) != 1)
    fail("cannot require TLS 1.2");
  beast::error_code ec;
  ctx->use_certificate_chain(asio::buffer(files->cert_chain), ec);
  if (ec) fail("cannot use the certificate in '" + o.tls_cert_file + "': " + ec.message());
  ctx->use_private_key(asio::buffer(files->private_key), asio::ssl::context::pem, ec);
  if (ec) fail("cannot use the private key in '" + o.tls_key_file + "': " + ec.message());
  if (!files->client_ca.empty()) {
    // Trust every certificate in the file for client certificates, and name them to clients.
    std::unique_ptr<BIO, decltype(&BIO_free)> bio(
        BIO_new_mem_buf(files->client_ca.data(), static_cast<int>(files->client_ca.size())),
        BIO_free);
    while (X509* x = PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr)) {
      const bool ok = X509_STORE_add_cert(SSL_CTX_get_cert_store(ctx->native_handle()), x) == 1 &&
                      SSL_CTX_add_client_CA(ctx->native_handle(), x) == 1;
      X509_free(x);
      if (!ok) fail("cannot use a certificate in '" + o.tls_client_ca_file + "'");
    }
    ctx->set_verify_mode(asio::ssl::verify_peer | asio::ssl::verify_fail_if_no_peer_cert);
  }
  ERR_clear_error();
  return ctx;
}

}  // namespace hdeform::gateway
