// `citylod serve TILESET_DIR`: a small static HTTP/1.1 server on 127.0.0.1 for
// the tileset, the CesiumJS viewer (examples/viewer) and CesiumJS itself
// (node_modules/cesium/Build/Cesium), so that everything works offline.
//
//   /                 -> VIEWER/index.html
//   /tileset/<path>   -> TILESET_DIR/<path>
//   /cesium/<path>    -> CESIUM/<path>
//   /<path>           -> VIEWER/<path>
//
// Hardening: symbolic links are resolved and a file must lie under its root;
// at most 128 connections (then 503), request headers within 10 s, idle
// connections closed after 15 s, clients that read nothing dropped after 30 s;
// files streamed in 64 KiB pieces; Range requests honoured for byte ranges: one
// range -> 206 with Content-Range, several -> 206 multipart/byteranges
// (overlapping and adjacent ones coalesced, at most 64), none satisfiable -> 416,
// a malformed Range or another unit -> the whole file (200), as RFC 9110 says; a
// request line over 64 KiB -> 414, headers over it -> 431; CORS only with --cors.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "citylod/tiler/workdir.hpp"
#include "cli.hpp"

namespace citylod::app {

namespace {

namespace fs = std::filesystem;

struct Roots {
  fs::path tileset, viewer, cesium;
};

/// The source tree this binary was built from (for the default viewer path).
#ifndef CITYLOD_SOURCE_DIR
#define CITYLOD_SOURCE_DIR "."
#endif
/// The source tree this binary was built from (examples/viewer, CesiumJS from npm).
fs::path source_root() {
  return fs::path(CITYLOD_SOURCE_DIR);
}

fs::path find_cesium(const fs::path& viewer) {
  if (const char* e = std::getenv("CITYLOD_CESIUM_DIR")) return e;
  for (const fs::path& p : {viewer / "node_modules/cesium/Build/Cesium",
                            source_root() / "examples/viewer/node_modules/cesium/Build/Cesium",
                            source_root() / "tests/node/node_modules/cesium/Build/Cesium"})
    if (fs::exists(p / "Cesium.js")) return p;
  return {};
}

const char* mime_type(const std::string& ext) {
  static const std::pair<const char*, const char*> kTypes[] = {
      {".html", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".json", "application/json"},
      {".glb", "model/gltf-binary"},
      {".gltf", "model/gltf+json"},
      {".b3dm", "application/octet-stream"},
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".jpeg", "image/jpeg"},
      {".svg", "image/svg+xml"},
      {".wasm", "application/wasm"},
      {".xml", "application/xml"},
      {".ktx2", "image/ktx2"},
      {".woff", "font/woff"},
      {".woff2", "font/woff2"},
      {".txt", "text/plain; charset=utf-8"},
      {".ico", "image/x-icon"}};
  for (const auto& [e, t] : kTypes)
    if (ext == e) return t;
  return "application/octet-stream";
}

std::string url_decode(const std::string& s, bool& ok) {
  std::string out;
  ok = true;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%') {
      if (i + 2 >= s.size() || !std::isxdigit(static_cast<unsigned char>(s[i + 1])) ||
          !std::isxdigit(static_cast<unsigned char>(s[i + 2]))) {
        ok = false;
        return {};
      }
      out.push_back(char(std::stoi(s.substr(i + 1, 2), nullptr, 16)));
      i += 2;
    } else {
      out.push_back(s[i]);
    }
  }
  return out;
}

/// True when `p` is `root` or lies under it (both canonical).
bool within(const fs::path& p, const fs::path& root) {
  auto r = root.begin(), q = p.begin();
  for (; r != root.end(); ++r, ++q)
    if (q == p.end() || *q != *r) return false;
  return true;
}

/// Maps a request path to a file under one of the roots; empty when the path
/// is malformed or escapes its root. Symbolic links are resolved (realpath)
/// and the file must still lie under its (canonical) root: nothing outside
/// the tileset, the viewer and CesiumJS is ever served.
fs::path resolve(const Roots& r, const std::string& raw_path) {
  std::string path = raw_path.substr(0, raw_path.find_first_of("?#"));
  bool ok = true;
  path = url_decode(path, ok);
  if (!ok || path.empty() || path[0] != '/' || path.find('\0') != std::string::npos) return {};
  fs::path root;
  std::string rest;
  if (path == "/") {
    root = r.viewer;
    rest = "index.html";
  } else if (path.rfind("/tileset/", 0) == 0) {
    root = r.tileset;
    rest = path.substr(9);
  } else if (path.rfind("/cesium/", 0) == 0) {
    if (r.cesium.empty()) return {};
    root = r.cesium;
    rest = path.substr(8);
  } else {
    root = r.viewer;
    rest = path.substr(1);
  }
  const fs::path rel = fs::path(rest).lexically_normal();
  if (rel.empty() || rel.is_absolute()) return {};
  for (const auto& part : rel)
    if (part == "..") return {};
  std::error_code ec;
  const fs::path real = fs::canonical(root / rel, ec);
  if (ec) return root / rel;  // missing: 404
  if (!within(real, root)) return {};
  return real;
}

bool send_all(int fd, const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t k = ::send(fd, p, n, MSG_NOSIGNAL);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return false;  // error or send timeout (a client that does not read)
    p += k;
    n -= std::size_t(k);
  }
  return true;
}

struct ServeOptions {
  bool cors = false;
};

std::string headers(int code, const char* reason, const std::string& type, std::uint64_t length,
                    bool keep_alive, const ServeOptions& o, const std::string& extra = "") {
  std::ostringstream h;
  h << "HTTP/1.1 " << code << ' ' << reason << "\r\n"
    << "Content-Type: " << type << "\r\n"
    << "Content-Length: " << length << "\r\n"
    << "Cache-Control: no-cache\r\n"
    << "Accept-Ranges: bytes\r\n"
    << extra << (o.cors ? "Access-Control-Allow-Origin: *\r\n" : "")
    << "Connection: " << (keep_alive ? "keep-alive" : "close") << "\r\n\r\n";
  return h.str();
}

bool respond(int fd, int code, const char* reason, const std::string& type, const std::string& body,
             bool head, bool keep_alive, const ServeOptions& o, const std::string& extra = "") {
  const std::string hs = headers(code, reason, type, body.size(), keep_alive, o, extra);
  if (!send_all(fd, hs.data(), hs.size())) return false;
  return head || send_all(fd, body.data(), body.size());
}

/// The value of header `name` (lower case, with ':') in a lower-cased request, or "".
std::string header_value(const std::string& lower, const std::string& name) {
  const auto at = lower.find("\r\n" + name);
  if (at == std::string::npos) return "";
  const auto b = at + 2 + name.size();
  const auto e = lower.find("\r\n", b);
  std::string v = lower.substr(b, e == std::string::npos ? std::string::npos : e - b);
  v.erase(0, v.find_first_not_of(" \t"));
  while (!v.empty() && (v.back() == ' ' || v.back() == '\t')) v.pop_back();
  return v;
}

/// A byte range [first, last] of a file.
struct ByteRange {
  std::uint64_t first = 0, last = 0;
};

constexpr std::size_t kMaxRanges = 64;  // more (after coalescing): the whole file, as RFC 9110 lets

/// The ranges of a Range header ("bytes=A-B, C-, -D", RFC 9110 section 14) for a
/// file of `size` bytes, sorted, overlapping and adjacent ones coalesced (RFC
/// 9110 14.2 lets a server do so). 0: serve the whole file (no Range header, a
/// unit other than bytes, a malformed set, which RFC 9110 says to ignore, or
/// more than kMaxRanges ranges); 1: `out` holds the ranges; -1: none is
/// satisfiable (416).
int parse_ranges(const std::string& value, std::uint64_t size, std::vector<ByteRange>& out) {
  out.clear();
  if (value.rfind("bytes=", 0) != 0) return 0;
  auto number = [](const std::string& t, std::uint64_t& v) {
    if (t.empty() || t.size() > 19 || t.find_first_not_of("0123456789") != std::string::npos)
      return false;
    v = std::stoull(t);
    return true;
  };
  const std::string set = value.substr(6);
  std::size_t specs = 0;
  for (std::size_t at = 0; at <= set.size();) {
    std::size_t comma = set.find(',', at);
    if (comma == std::string::npos) comma = set.size();
    std::string spec = set.substr(at, comma - at);
    at = comma + 1;
    spec.erase(0, spec.find_first_not_of(" \t"));
    while (!spec.empty() && (spec.back() == ' ' || spec.back() == '\t')) spec.pop_back();
    if (spec.empty()) continue;  // "a, , b": empty list elements are allowed
    if (++specs > 1024) return 0;
    const auto dash = spec.find('-');
    if (dash == std::string::npos) return 0;
    const std::string a = spec.substr(0, dash), b = spec.substr(dash + 1);
    std::uint64_t x = 0, y = 0;
    if (a.empty()) {  // the last y bytes
      if (!number(b, y)) return 0;
      if (y == 0 || size == 0) continue;
      out.push_back({size - std::min(y, size), size - 1});
      continue;
    }
    if (!number(a, x)) return 0;
    if (!b.empty() && (!number(b, y) || y < x)) return 0;
    if (x >= size) continue;
    out.push_back({x, b.empty() ? size - 1 : std::min(y, size - 1)});
  }
  if (specs == 0) return 0;
  if (out.empty()) return -1;
  std::sort(out.begin(), out.end(),
            [](const ByteRange& p, const ByteRange& q) { return p.first < q.first; });
  std::vector<ByteRange> merged;
  for (const ByteRange& r : out)
    if (!merged.empty() && r.first <= merged.back().last + 1)
      merged.back().last = std::max(merged.back().last, r.last);
    else
      merged.push_back(r);
  out = std::move(merged);
  if (out.size() > kMaxRanges) {
    out.clear();
    return 0;
  }
  return 1;
}

/// Streams [first, last] of an open file in 64 KiB pieces (never the whole file in memory).
bool send_file_range(int sock, int file, std::uint64_t first, std::uint64_t last) {
  std::vector<char> buf(1 << 16);
  for (std::uint64_t at = first; at <= last;) {
    const std::size_t want = std::size_t(std::min<std::uint64_t>(buf.size(), last - at + 1));
    const ssize_t k = ::pread(file, buf.data(), want, off_t(at));
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return false;  // the file shrank: the client sees a short body
    if (!send_all(sock, buf.data(), std::size_t(k))) return false;
    at += std::uint64_t(k);
  }
  return true;
}

using Clock = std::chrono::steady_clock;
constexpr int kHeaderSeconds = 10;  // a request's headers must arrive within this
constexpr int kIdleSeconds = 15;    // a kept-alive connection with no request is closed
constexpr int kSendSeconds = 30;    // a client that reads nothing for this long is dropped
constexpr std::size_t kMaxRequestBytes = 65536;  // request line and headers together

/// Waits until `fd` is readable or `deadline`; false on timeout.
bool wait_readable(int fd, Clock::time_point deadline) {
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return false;
    pollfd p{fd, POLLIN, 0};
    const int k = ::poll(&p, 1, int(std::min<long long>(left, 1000000)));
    if (k < 0 && errno == EINTR) continue;
    return k > 0;
  }
}

/// Closes after an early answer: the write side first, then what the client
/// still sends is read and dropped (up to 1 MiB or 2 s), so that the answer is
/// not lost to a reset from unread data (RFC 9112 9.6).
void lingering_close(int fd) {
  ::shutdown(fd, SHUT_WR);
  const auto deadline = Clock::now() + std::chrono::seconds(2);
  char sink[8192];
  for (std::size_t total = 0; total < (1u << 20) && wait_readable(fd, deadline);) {
    const ssize_t k = ::recv(fd, sink, sizeof sink, 0);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) break;
    total += std::size_t(k);
  }
  ::close(fd);
}

bool serve_file(int fd, const fs::path& file, const std::string& lower, bool head, bool keep,
                const ServeOptions& o, const std::string& target) {
  const int in = ::open(file.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
  struct stat st {};
  if (in < 0 || ::fstat(in, &st) != 0 || !S_ISREG(st.st_mode)) {
    if (in >= 0) ::close(in);
    return respond(fd, 404, "Not Found", "text/plain", "not found: " + target + "\n", head, keep,
                   o);
  }
  const std::uint64_t size = std::uint64_t(st.st_size);
  std::vector<ByteRange> ranges;
  const int range = parse_ranges(header_value(lower, "range:"), size, ranges);
  const std::string type = mime_type(file.extension().string());
  const auto content_range = [&](const ByteRange& r) {
    return "Content-Range: bytes " + std::to_string(r.first) + "-" + std::to_string(r.last) + "/" +
           std::to_string(size) + "\r\n";
  };
  bool ok;
  if (range < 0) {
    ok = respond(fd, 416, "Range Not Satisfiable", "text/plain", "range not satisfiable\n", head,
                 keep, o, "Content-Range: bytes */" + std::to_string(size) + "\r\n");
  } else if (range == 0 || ranges.size() == 1) {
    const ByteRange r = range ? ranges[0] : ByteRange{0, size ? size - 1 : 0};
    const std::uint64_t length = range ? r.last - r.first + 1 : size;
    const std::string hs = headers(range ? 206 : 200, range ? "Partial Content" : "OK", type,
                                   length, keep, o, range ? content_range(r) : "");
    ok = send_all(fd, hs.data(), hs.size()) &&
         (head || length == 0 || send_file_range(fd, in, r.first, r.first + length - 1));
  } else {
    // Several ranges: multipart/byteranges (RFC 9110 14.6), each part with its
    // own Content-Type and Content-Range; the length is known before sending.
    const std::string boundary = "citylod-byteranges-" + std::to_string(size);
    std::vector<std::string> heads;
    std::uint64_t length = 0;
    for (const ByteRange& r : ranges) {
      heads.push_back("\r\n--" + boundary + "\r\nContent-Type: " + type + "\r\n" +
                      content_range(r) + "\r\n");
      length += heads.back().size() + (r.last - r.first + 1);
    }
    const std::string tail = "\r\n--" + boundary + "--\r\n";
    length += tail.size();
    const std::string hs = headers(206, "Partial Content",
                                   "multipart/byteranges; boundary=" + boundary, length, keep, o);
    ok = send_all(fd, hs.data(), hs.size());
    for (std::size_t k = 0; ok && !head && k < ranges.size(); ++k)
      ok = send_all(fd, heads[k].data(), heads[k].size()) &&
           send_file_range(fd, in, ranges[k].first, ranges[k].last);
    if (ok && !head) ok = send_all(fd, tail.data(), tail.size());
  }
  log_debug("serve: " + std::to_string(range < 0 ? 416 : range ? 206 : 200) + " " + target);
  ::close(in);
  return ok;
}

void handle_connection(int fd, const Roots& roots, const ServeOptions& o) {
  timeval tv{kSendSeconds, 0};
  setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  std::string buf;
  char chunk[8192];
  for (;;) {
    // The first byte of a request within the idle time, all its headers within kHeaderSeconds.
    const auto idle_deadline = Clock::now() + std::chrono::seconds(kIdleSeconds);
    Clock::time_point deadline = idle_deadline;
    bool started = !buf.empty();
    if (started) deadline = Clock::now() + std::chrono::seconds(kHeaderSeconds);
    std::size_t end;
    while ((end = buf.find("\r\n\r\n")) == std::string::npos) {
      if (buf.size() > kMaxRequestBytes) {
        // RFC 9110 15.5.15 / RFC 6585 5: a request line too long is 414, headers 431
        if (buf.find("\r\n") == std::string::npos || buf.find("\r\n") > kMaxRequestBytes)
          respond(fd, 414, "URI Too Long", "text/plain", "request line too long\n", false, false,
                  o);
        else
          respond(fd, 431, "Request Header Fields Too Large", "text/plain",
                  "request headers too large\n", false, false, o);
        lingering_close(fd);
        return;
      }
      if (!wait_readable(fd, deadline)) {
        ::close(fd);
        return;
      }
      const ssize_t k = ::recv(fd, chunk, sizeof chunk, 0);
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) {
        ::close(fd);
        return;
      }
      buf.append(chunk, std::size_t(k));
      if (!started) {
        started = true;
        deadline = Clock::now() + std::chrono::seconds(kHeaderSeconds);
      }
    }
    const std::string req = buf.substr(0, end + 2);
    buf.erase(0, end + 4);
    std::istringstream rs(req);
    std::string method, target, version;
    rs >> method >> target >> version;
    std::string lower = req;
    for (auto& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    const bool keep = version == "HTTP/1.1" && header_value(lower, "connection:") != "close";
    const bool head = method == "HEAD";
    bool alive = true;
    if (method != "GET" && !head) {
      respond(fd, 405, "Method Not Allowed", "text/plain", "method not allowed\n", false, false, o);
      alive = false;
    } else {
      const fs::path file = resolve(roots, target);
      std::error_code ec;
      if (file.empty()) {
        alive = respond(fd, 400, "Bad Request", "text/plain", "bad path\n", head, keep, o);
      } else if (!fs::is_regular_file(file, ec)) {
        log_debug("serve: 404 " + target);
        alive = respond(fd, 404, "Not Found", "text/plain", "not found: " + target + "\n", head,
                        keep, o);
      } else {
        alive = serve_file(fd, file, lower, head, keep, o, target);
      }
    }
    if (!alive || !keep) break;
  }
  ::close(fd);
}

}  // namespace

int cmd_serve(ArgParser& args) {
  args.usage("TILESET_DIR")
      .describe(
          "Serve a tileset and the CesiumJS viewer (examples/viewer) on http://127.0.0.1:PORT/\n"
          "for local viewing, offline: CesiumJS comes from node_modules (install it with\n"
          "scripts/install-node-tools.sh). The URL is printed on stdout; stop with Ctrl-C.");
  args.option("port", 'p', "PORT", "TCP port on 127.0.0.1 (0 = any free port)", "8080");
  args.option("viewer", 0, "DIR", "viewer files (default: examples/viewer of the source tree)");
  args.option("cesium", 0, "DIR",
              "CesiumJS Build/Cesium directory (default: found in node_modules)");
  args.flag("cors", 0,
            "send 'Access-Control-Allow-Origin: *' (lets pages of other origins load the "
            "tileset; off by default)");
  args.positional("TILESET_DIR", "directory with tileset.json", Arity::one);
  if (!args.parse()) return 0;
  ServeOptions so;
  so.cors = args.has("cors");

  Roots roots;
  roots.tileset = fs::absolute(args.positionals().at(0));
  if (!fs::exists(tiler::tileset_json_path(roots.tileset.string())))
    throw std::runtime_error(roots.tileset.string() +
                             ": no tileset.json (run 'citylod assemble' first)");
  roots.viewer = args.has("viewer")                  ? fs::path(args.get("viewer"))
                 : std::getenv("CITYLOD_VIEWER_DIR") ? fs::path(std::getenv("CITYLOD_VIEWER_DIR"))
                                                     : source_root() / "examples/viewer";
  roots.viewer = fs::absolute(roots.viewer);
  if (!fs::exists(roots.viewer / "index.html"))
    throw std::runtime_error(roots.viewer.string() +
                             ": no index.html (give the viewer directory with --viewer)");
  roots.cesium = args.has("cesium") ? fs::absolute(args.get("cesium")) : find_cesium(roots.viewer);
  if (roots.cesium.empty() || !fs::exists(roots.cesium / "Cesium.js")) {
    log_warn(
        "CesiumJS not found (run scripts/install-node-tools.sh or give --cesium DIR): the viewer "
        "will not start");
    roots.cesium.clear();
  }
  // Canonical roots (symbolic links resolved): a served file's real path must lie under one.
  for (fs::path* r : {&roots.tileset, &roots.viewer, &roots.cesium})
    if (!r->empty()) *r = fs::canonical(*r);
  const auto port = args.get_int("port");
  if (port < 0 || port > 65535) throw UsageError("--port must be 0..65535");

  const int srv = ::socket(AF_INET, SOCK_STREAM, 0);
  if (srv < 0) throw std::runtime_error(std::string("socket: ") + std::strerror(errno));
  const int one = 1;
  setsockopt(srv, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(std::uint16_t(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::bind(srv, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0 || ::listen(srv, 64) < 0) {
    const std::string why = std::strerror(errno);
    ::close(srv);
    throw std::runtime_error("cannot listen on 127.0.0.1:" + std::to_string(port) + ": " + why);
  }
  socklen_t len = sizeof addr;
  getsockname(srv, reinterpret_cast<sockaddr*>(&addr), &len);
  std::printf("serving %s on http://127.0.0.1:%d/\n", roots.tileset.string().c_str(),
              int(ntohs(addr.sin_port)));
  std::fflush(stdout);
  ::signal(SIGPIPE, SIG_IGN);

  // Bounded connections, one thread each: beyond kMaxConnections a client gets
  // 503 at once (the accept loop never blocks on a slow client).
  constexpr int kMaxConnections = 128;
  std::atomic<int> active{0};
  for (;;) {
    const int fd = ::accept4(srv, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      if (errno == EMFILE || errno == ENFILE) {  // out of descriptors: let some close
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        continue;
      }
      const std::string why = std::strerror(errno);
      ::close(srv);
      throw std::runtime_error("accept: " + why);
    }
    if (active.load() >= kMaxConnections) {
      timeval tv{1, 0};
      setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
      respond(fd, 503, "Service Unavailable", "text/plain", "too many connections\n", false, false,
              so, "Retry-After: 1\r\n");
      ::close(fd);
      continue;
    }
    ++active;
    std::thread([fd, &roots, &active, so] {
      handle_connection(fd, roots, so);
      --active;
    }).detach();
  }
}

}  // namespace citylod::app
