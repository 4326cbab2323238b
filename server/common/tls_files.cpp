#include "common/tls_files.h"

#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

namespace hdeform::service {

namespace {

struct Named {
  const std::string& program;
  std::string what;
  const std::string& path;

  [[noreturn]] void fail(const std::string& why) const {
    ERR_clear_error();
    throw std::runtime_error(program + ": " + what + " '" + path + "': " + why);
  }

  // The whole PEM file (at most 16 MiB is read).
  std::string read() const {
    constexpr std::size_t kMaxBytes = 16u << 20;
    std::unique_ptr<std::FILE, decltype(&std::fclose)> f(std::fopen(path.c_str(), "rb"),
                                                         std::fclose);
    if (!f) fail(std::string("cannot open: ") + std::strerror(errno));
    std::string bytes;
    char buffer[8192];
    std::size_t n = 0;
    while (bytes.size() <= kMaxBytes && (n = std::fread(buffer, 1, sizeof buffer, f.get())) > 0)
      bytes.append(buffer, n);
    if (std::ferror(f.get())) fail(std::string("cannot read: ") + std::strerror(errno));
    if (bytes.size() > kMaxBytes) fail("larger than 16 MiB; not a PEM file");
    return bytes;
  }
};

// Never ask for a pass phrase (OpenSSL's default would prompt on the terminal).
int no_pass_phrase(char*, int, int, void*) { return 0; }

using BioPtr = std::unique_ptr<BIO, decltype(&BIO_free)>;
BioPtr memory_bio(const std::string& bytes) {
  return BioPtr(BIO_new_mem_buf(bytes.data(), static_cast<int>(bytes.size())), BIO_free);
}

}  // namespace

std::optional<TlsFiles> load_tls_files(const std::string& program, const std::string& cert_file,
                                       const std::string& key_file,
                                       const std::string& client_ca_file) {
  if (cert_file.empty() && key_file.empty()) {
    if (!client_ca_file.empty())
      throw std::runtime_error(program + ": --tls-client-ca needs --tls-cert and --tls-key");
    return std::nullopt;
  }
  if (cert_file.empty() || key_file.empty()) {
    throw std::runtime_error(program + ": TLS needs both --tls-cert and --tls-key (" +
                             (cert_file.empty() ? "--tls-cert" : "--tls-key") + " is missing)");
  }
  const Named cert_named{program, "TLS certificate (--tls-cert)", cert_file};
  const Named key_named{program, "TLS private key (--tls-key)", key_file};
  TlsFiles files;
  files.cert_chain = cert_named.read();
  files.private_key = key_named.read();

  auto cert_bio = memory_bio(files.cert_chain);
  std::unique_ptr<X509, decltype(&X509_free)> cert(
      PEM_read_bio_X509(cert_bio.get(), nullptr, no_pass_phrase, nullptr), X509_free);
  if (!cert) cert_named.fail("no PEM certificate in it");
  auto key_bio = memory_bio(files.private_key);
  std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(
      PEM_read_bio_PrivateKey(key_bio.get(), nullptr, no_pass_phrase, nullptr), EVP_PKEY_free);
  if (!key)
    key_named.fail("no PEM private key in it (or it is encrypted: pass phrases are not supported)");
  if (X509_check_private_key(cert.get(), key.get()) != 1)
    key_named.fail("does not match the certificate in '" + cert_file + "'");

  if (!client_ca_file.empty()) {
    const Named ca_named{program, "TLS client CA (--tls-client-ca)", client_ca_file};
    files.client_ca = ca_named.read();
    auto ca_bio = memory_bio(files.client_ca);
    std::unique_ptr<X509, decltype(&X509_free)> ca(
        PEM_read_bio_X509(ca_bio.get(), nullptr, no_pass_phrase, nullptr), X509_free);
    if (!ca) ca_named.fail("no PEM certificate in it");
  }
  ERR_clear_error();
  return files;
}

}  // namespace hdeform::service
