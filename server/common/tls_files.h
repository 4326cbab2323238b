// The TLS files of both doors (gRPC and the HTTP gateway; docs/deployment.md "TLS"), read and
// checked before anything listens. gRPC reports a bad certificate or key only as "cannot
// bind", so every check here names the flag and the file at fault.
#pragma once

#include <optional>
#include <string>

namespace hdeform::service {

struct TlsFiles {
  std::string cert_chain;   // PEM bytes of --tls-cert
  std::string private_key;  // PEM bytes of --tls-key (unencrypted)
  std::string client_ca;    // PEM bytes of --tls-client-ca; empty when clients are not verified
};

// nullopt when no TLS flag is given. Throws std::runtime_error "<program>: <flag> '<path>':
// <why>" when a file cannot be read (at most 16 MiB each), holds no PEM certificate or key, the
// key is encrypted or does not match the certificate, or --tls-client-ca comes without the
// other two.
std::optional<TlsFiles> load_tls_files(const std::string& program, const std::string& cert_file,
                                       const std::string& key_file,
                                       const std::string& client_ca_file);

}  // namespace hdeform::service
