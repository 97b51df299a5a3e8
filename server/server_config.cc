#include "server/server_config.h"

#include <arpa/inet.h>
#include <netinet/in.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <sstream>
#include <tuple>
#include <type_traits>

#include "absl/strings/str_cat.h"
#include "mlsreg/io/io.h"
#include "nlohmann/json.hpp"

namespace mlsreg::server {
namespace {

using Json = nlohmann::json;

// One setter per key: it checks the JSON type and stores the value.
using FieldSetter = std::function<absl::Status(const Json&, ServerConfig*)>;

template <typename T>
FieldSetter Set(const char* key, T ServerConfig::*member) {
  return [key, member](const Json& value, ServerConfig* config) -> absl::Status {
    auto type_error = [&](const char* expected) {
      return absl::InvalidArgumentError(
          absl::StrCat("config key '", key, "': expected ", expected, ", got ", value.dump()));
    };
    if constexpr (std::is_same_v<T, std::string>) {
      if (!value.is_string()) return type_error("a string");
      config->*member = value.get<std::string>();
    } else if constexpr (std::is_same_v<T, bool>) {
      if (!value.is_boolean()) return type_error("true or false");
      config->*member = value.get<bool>();
    } else if constexpr (std::is_same_v<T, double>) {
      if (!value.is_number()) return type_error("a number");
      config->*member = value.get<double>();
    } else if constexpr (std::is_same_v<T, std::uint64_t>) {
      if (!value.is_number_unsigned()) return type_error("a non-negative integer");
      config->*member = value.get<std::uint64_t>();
    } else {
      static_assert(std::is_same_v<T, int>);
      if (!value.is_number_integer()) return type_error("an integer");
      const auto v = value.get<std::int64_t>();
      if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) {
        return type_error("an integer in the int range");
      }
      config->*member = static_cast<int>(v);
    }
    return absl::OkStatus();
  };
}

const std::map<std::string, FieldSetter>& Setters() {
  static const auto* setters = new std::map<std::string, FieldSetter>{
      {"listen", Set("listen", &ServerConfig::listen)},
      {"metrics_listen", Set("metrics_listen", &ServerConfig::metrics_listen)},
      {"workers", Set("workers", &ServerConfig::workers)},
      {"queue_capacity", Set("queue_capacity", &ServerConfig::queue_capacity)},
      {"job_threads", Set("job_threads", &ServerConfig::job_threads)},
      {"cache_budget_bytes", Set("cache_budget_bytes", &ServerConfig::cache_budget_bytes)},
      {"data_dir", Set("data_dir", &ServerConfig::data_dir)},
      {"max_points", Set("max_points", &ServerConfig::max_points)},
      {"max_message_bytes", Set("max_message_bytes", &ServerConfig::max_message_bytes)},
      {"max_chunk_bytes", Set("max_chunk_bytes", &ServerConfig::max_chunk_bytes)},
      {"max_concurrent_rpcs", Set("max_concurrent_rpcs", &ServerConfig::max_concurrent_rpcs)},
      {"tls_cert", Set("tls_cert", &ServerConfig::tls_cert)},
      {"tls_key", Set("tls_key", &ServerConfig::tls_key)},
      {"tls_client_ca", Set("tls_client_ca", &ServerConfig::tls_client_ca)},
      {"allow_insecure_remote", Set("allow_insecure_remote", &ServerConfig::allow_insecure_remote)},
      {"token", Set("token", &ServerConfig::token)},
      {"admin_token", Set("admin_token", &ServerConfig::admin_token)},
      {"drain_seconds", Set("drain_seconds", &ServerConfig::drain_seconds)},
      {"max_inflight_bytes", Set("max_inflight_bytes", &ServerConfig::max_inflight_bytes)},
      {"max_streams_per_peer", Set("max_streams_per_peer", &ServerConfig::max_streams_per_peer)},
      {"max_streams_per_client",
       Set("max_streams_per_client", &ServerConfig::max_streams_per_client)},
      {"max_streams_per_connection",
       Set("max_streams_per_connection", &ServerConfig::max_streams_per_connection)},
      {"idle_timeout_seconds", Set("idle_timeout_seconds", &ServerConfig::idle_timeout_seconds)},
      {"reflection", Set("reflection", &ServerConfig::reflection)},
      {"token_file", Set("token_file", &ServerConfig::token_file)},
      {"admin_token_file", Set("admin_token_file", &ServerConfig::admin_token_file)},
  };
  return *setters;
}

// The host part of host:port, without IPv6 brackets.
std::string HostOf(const std::string& listen) {
  if (!listen.empty() && listen.front() == '[') {
    const std::size_t close = listen.find(']');
    return close == std::string::npos ? listen : listen.substr(1, close - 1);
  }
  const std::size_t colon = listen.rfind(':');
  return colon == std::string::npos ? listen : listen.substr(0, colon);
}

// "--max-streams-per-peer" for the key max_streams_per_peer: `mlsreg serve`'s flag.
std::string FlagOf(const char* key) {
  std::string flag = absl::StrCat("--", key);
  std::replace(flag.begin(), flag.end(), '_', '-');
  return flag;
}

// InvalidArgument "<key> (<flag>): <rule>", so both a config file and a command line are named.
absl::Status Bad(const char* key, const std::string& rule) {
  return absl::InvalidArgumentError(absl::StrCat(key, " (", FlagOf(key), "): ", rule));
}

// A listening address: unix sockets as gRPC spells them, else HOST:PORT with a port in
// [0, 65535] (0: any free port). gRPC would take a larger number modulo 65536.
absl::Status CheckListenAddress(const char* key, const std::string& address) {
  if (address.rfind("unix:", 0) == 0 || address.rfind("unix-abstract:", 0) == 0) {
    return absl::OkStatus();
  }
  const std::size_t colon = address.rfind(':');
  const std::size_t bracket = address.rfind(']');
  if (colon == std::string::npos || (bracket != std::string::npos && colon < bracket)) {
    return Bad(key, absl::StrCat("'", address, "' is not HOST:PORT"));
  }
  const std::string port = address.substr(colon + 1);
  const bool digits =
      !port.empty() && port.size() <= 9 && std::all_of(port.begin(), port.end(), [](char c) {
        return std::isdigit(static_cast<unsigned char>(c));
      });
  if (!digits) {
    return Bad(key, absl::StrCat("'", address, "' has no port number after the last ':'"));
  }
  if (std::stoi(port) > 65535) {
    return Bad(key, absl::StrCat("port ", port, " in '", address,
                                 "' is out of range: ports are 0 to 65535 (0: any free port)"));
  }
  if (colon == 0) return Bad(key, absl::StrCat("'", address, "' has no host before the port"));
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::string> ReadTextFile(const std::string& path, const std::string& what) {
  absl::StatusOr<std::string> bytes = ReadFileBytes(path);
  if (!bytes.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": cannot read file '", path, "' (", bytes.status().message(), ")"));
  }
  return bytes;
}

absl::Status LoadConfigFile(const std::string& path, ServerConfig* config) {
  auto text = ReadTextFile(path, "config");
  if (!text.ok()) return text.status();
  const Json json = Json::parse(*text, /*cb=*/nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded()) {
    return absl::InvalidArgumentError(absl::StrCat("config '", path, "': not valid JSON"));
  }
  if (!json.is_object()) {
    return absl::InvalidArgumentError(absl::StrCat("config '", path, "': expected a JSON object"));
  }
  for (const auto& [key, value] : json.items()) {
    const auto setter = Setters().find(key);
    if (setter == Setters().end()) {
      return absl::InvalidArgumentError(
          absl::StrCat("config '", path, "': unknown key '", key, "'"));
    }
    if (absl::Status s = setter->second(value, config); !s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("config '", path, "': ", s.message()));
    }
  }
  return absl::OkStatus();
}

bool IsLoopbackAddress(const std::string& listen) {
  if (listen.rfind("unix:", 0) == 0 || listen.rfind("unix-abstract:", 0) == 0) return true;
  const std::string host = HostOf(listen);
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1) {
    if (IN6_IS_ADDR_LOOPBACK(&v6)) return true;
    // ::ffff:127.x.y.z, IPv4-mapped loopback
    return IN6_IS_ADDR_V4MAPPED(&v6) && v6.s6_addr[12] == 127;
  }
  return false;
}

absl::Status LoadTokenFiles(ServerConfig* config) {
  for (auto [file, token, what] :
       {std::tuple{&config->token_file, &config->token, "token_file"},
        std::tuple{&config->admin_token_file, &config->admin_token, "admin_token_file"}}) {
    if (file->empty()) continue;
    auto text = ReadTextFile(*file, what);
    if (!text.ok()) return text.status();
    std::string value = *text;
    while (!value.empty() && std::isspace(static_cast<unsigned char>(value.back()))) {
      value.pop_back();
    }
    if (value.empty()) {
      return absl::InvalidArgumentError(absl::StrCat(what, ": file '", *file, "' is empty"));
    }
    if (token == &config->admin_token && value.find('\n') != std::string::npos) {
      return absl::InvalidArgumentError(
          absl::StrCat(what, ": file '", *file, "' holds more than one line: one admin token"));
    }
    *token = value;  // token_file: one user token per line (TokenAuthenticator splits them)
  }
  return absl::OkStatus();
}

absl::Status Validate(const ServerConfig& c) {
  auto bad = [](const char* field, const std::string& rule) { return Bad(field, rule); };
  if (absl::Status s = CheckListenAddress("listen", c.listen); !s.ok()) return s;
  if (!c.metrics_listen.empty()) {
    if (absl::Status s = CheckListenAddress("metrics_listen", c.metrics_listen); !s.ok()) {
      return s;
    }
  }
  if (c.workers < 0 || c.workers > 1024) return bad("workers", "must be in [0, 1024]");
  if (c.job_threads < 1 || c.job_threads > 256) return bad("job_threads", "must be in [1, 256]");
  if (c.queue_capacity < 0 || c.queue_capacity > 1'000'000) {
    return bad("queue_capacity", "must be in [0, 1000000]");
  }
  if (c.cache_budget_bytes == 0) return bad("cache_budget_bytes", "must be > 0");
  if (c.max_points == 0) return bad("max_points", "must be > 0");
  if (c.max_chunk_bytes <= 0) return bad("max_chunk_bytes", "must be > 0");
  // A message must be able to carry a full chunk plus its few bytes of framing.
  if (c.max_message_bytes < c.max_chunk_bytes + 1024) {
    return bad("max_message_bytes", "must be at least max_chunk_bytes + 1024");
  }
  if (c.max_concurrent_rpcs < 4) return bad("max_concurrent_rpcs", "must be >= 4");
  if (c.max_inflight_bytes == 0) return bad("max_inflight_bytes", "must be > 0");
  if (c.max_streams_per_peer < 1) return bad("max_streams_per_peer", "must be >= 1");
  if (c.max_streams_per_client < 1) return bad("max_streams_per_client", "must be >= 1");
  if (c.max_streams_per_connection < 1) return bad("max_streams_per_connection", "must be >= 1");
  if (!(c.idle_timeout_seconds >= 0.05 && c.idle_timeout_seconds <= 86400.0)) {
    return bad("idle_timeout_seconds", "must be in [0.05, 86400]");
  }
  if (!c.token.empty() && !c.token_file.empty()) {
    return bad("token_file", "give token or token_file, not both");
  }
  if (!c.admin_token.empty() && !c.admin_token_file.empty()) {
    return bad("admin_token_file", "give admin_token or admin_token_file, not both");
  }
  {
    ServerConfig tokens = c;
    if (absl::Status s = LoadTokenFiles(&tokens); !s.ok()) return s;
  }
  if (!(c.drain_seconds >= 0.0 && c.drain_seconds <= 3600.0)) {
    return bad("drain_seconds", "must be in [0, 3600]");
  }
  if (c.tls_cert.empty() != c.tls_key.empty()) {
    return bad("tls_cert", "tls_cert and tls_key must be set together");
  }
  if (!c.tls_client_ca.empty() && c.tls_cert.empty()) {
    return bad("tls_client_ca", "mutual TLS needs tls_cert and tls_key too");
  }
  for (const auto& [field, path] :
       {std::pair{"tls_cert", &c.tls_cert}, std::pair{"tls_key", &c.tls_key},
        std::pair{"tls_client_ca", &c.tls_client_ca}}) {
    if (path->empty()) continue;
    if (auto text = ReadTextFile(*path, field); !text.ok()) return text.status();
  }
  if (c.tls_cert.empty() && !c.allow_insecure_remote && !IsLoopbackAddress(c.listen)) {
    return absl::FailedPreconditionError(
        absl::StrCat("refusing to serve plaintext on non-loopback address '", c.listen,
                     "': set tls_cert and tls_key, or allow_insecure_remote when a TLS proxy "
                     "fronts the server"));
  }
  return absl::OkStatus();
}

}  // namespace mlsreg::server
