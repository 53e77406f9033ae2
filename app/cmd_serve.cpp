// `citylod serve TILESET_DIR`: a small static HTTP/1.1 server on 127.0.0.1 for
// the tileset, the CesiumJS viewer (examples/viewer) and CesiumJS itself
// (node_modules/cesium/Build/Cesium), so that everything works offline.
//
//   /                 -> VIEWER/index.html
//   /tileset/<path>   -> TILESET_DIR/<path>
//   /cesium/<path>    -> CESIUM/<path>
//   /<path>           -> VIEWER/<path>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

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

/// Maps a request path to a file under one of the roots; empty when the path
/// is malformed or escapes its root.
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
  return root / rel;
}

bool send_all(int fd, const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t k = ::send(fd, p, n, MSG_NOSIGNAL);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return false;
    p += k;
    n -= std::size_t(k);
  }
  return true;
}

bool respond(int fd, int code, const char* reason, const std::string& type, const std::string& body,
             bool head, bool keep_alive) {
  std::ostringstream h;
  h << "HTTP/1.1 " << code << ' ' << reason << "\r\n"
    << "Content-Type: " << type << "\r\n"
    << "Content-Length: " << body.size() << "\r\n"
    << "Cache-Control: no-cache\r\n"
    << "Access-Control-Allow-Origin: *\r\n"
    << "Connection: " << (keep_alive ? "keep-alive" : "close") << "\r\n\r\n";
  const std::string hs = h.str();
  if (!send_all(fd, hs.data(), hs.size())) return false;
  return head || send_all(fd, body.data(), body.size());
}

void handle_connection(int fd, const Roots& roots) {
  timeval tv{10, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::string buf;
  char chunk[8192];
  for (;;) {
    std::size_t end;
    while ((end = buf.find("\r\n\r\n")) == std::string::npos) {
      if (buf.size() > 65536) {
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
    }
    const std::string req = buf.substr(0, end);
    buf.erase(0, end + 4);
    std::istringstream rs(req);
    std::string method, target, version;
    rs >> method >> target >> version;
    std::string lower = req;
    for (auto& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    const bool keep = version == "HTTP/1.1" && lower.find("connection: close") == std::string::npos;
    const bool head = method == "HEAD";
    bool alive = true;
    if (method != "GET" && !head) {
      alive = respond(fd, 405, "Method Not Allowed", "text/plain", "method not allowed\n", false,
                      false) &&
              false;
    } else {
      const fs::path file = resolve(roots, target);
      std::error_code ec;
      if (file.empty()) {
        alive = respond(fd, 400, "Bad Request", "text/plain", "bad path\n", head, keep);
      } else if (!fs::is_regular_file(file, ec)) {
        log_debug("serve: 404 " + target);
        alive =
            respond(fd, 404, "Not Found", "text/plain", "not found: " + target + "\n", head, keep);
      } else {
        std::ifstream in(file, std::ios::binary);
        std::ostringstream body;
        body << in.rdbuf();
        log_debug("serve: 200 " + target);
        alive =
            respond(fd, 200, "OK", mime_type(file.extension().string()), body.str(), head, keep);
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
  args.positional("TILESET_DIR", "directory with tileset.json", Arity::one);
  if (!args.parse()) return 0;

  Roots roots;
  roots.tileset = fs::absolute(args.positionals().at(0));
  if (!fs::exists(roots.tileset / "tileset.json"))
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

  std::atomic<int> active{0};
  for (;;) {
    const int fd = ::accept(srv, nullptr, nullptr);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      const std::string why = std::strerror(errno);
      ::close(srv);
      throw std::runtime_error("accept: " + why);
    }
    if (active.load() >= 64) {  // plenty for one browser; serve inline beyond that
      handle_connection(fd, roots);
      continue;
    }
    ++active;
    std::thread([fd, &roots, &active] {
      handle_connection(fd, roots);
      --active;
    }).detach();
  }
}

}  // namespace citylod::app
