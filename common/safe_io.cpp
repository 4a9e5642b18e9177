#include "gridrt/common/safe_io.h"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <filesystem>
#include <optional>
#include <cstdio>
#include <iostream>
#include <map>
#include <mutex>

#include <csignal>
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

namespace gridrt {
namespace fs = std::filesystem;

InputLimits& input_limits() {
  static InputLimits limits;
  return limits;
}

namespace {

// The first number of the file at `path` (times `scale`), or nullopt where it cannot be read or
// holds none ("max" in a cgroup's memory.max).
std::optional<uint64_t> read_number(const char* path, const char* key, uint64_t scale) {
  std::FILE* f = std::fopen(path, "r");
  if (!f) return std::nullopt;
  char line[256];
  std::optional<uint64_t> value;
  while (std::fgets(line, sizeof line, f)) {
    const char* p = line;
    if (key) {
      if (std::strncmp(line, key, std::strlen(key)) != 0) continue;
      p += std::strlen(key);
    }
    char* end = nullptr;
    errno = 0;
    const unsigned long long v = std::strtoull(p, &end, 10);
    if (end != p && errno == 0) value = uint64_t(v) * scale;
    break;
  }
  std::fclose(f);
  return value;
}

}  // namespace

uint64_t host_memory_available() {
  uint64_t room = UINT64_MAX;
  if (const auto a = read_number("/proc/meminfo", "MemAvailable:", 1024)) room = std::min(room, *a);
  const auto max = read_number("/sys/fs/cgroup/memory.max", nullptr, 1);
  const auto current = read_number("/sys/fs/cgroup/memory.current", nullptr, 1);
  if (max && current) room = std::min(room, *max > *current ? *max - *current : 0);
  // The limits on this process count what it already holds (the machine's and the cgroup's
  // figures above already leave it out): the address space against ulimit -v, the data segment
  // against ulimit -d, the resident set against --max-host-mib (the peak /usr/bin/time reports)
  const auto left = [](uint64_t limit, std::optional<uint64_t> held) { return held && *held < limit ? limit - *held : held ? 0 : limit; };
  const auto vm_size = read_number("/proc/self/status", "VmSize:", 1024);
  const auto vm_data = read_number("/proc/self/status", "VmData:", 1024);
  const auto vm_rss = read_number("/proc/self/status", "VmRSS:", 1024);
  for (const int resource : {RLIMIT_AS, RLIMIT_DATA}) {
    rlimit r{};
    if (getrlimit(resource, &r) == 0 && r.rlim_cur != RLIM_INFINITY)
      room = std::min(room, left(uint64_t(r.rlim_cur), resource == RLIMIT_AS ? vm_size : vm_data));
  }
  // --max-host-mib counts what the grids take: the resident set beyond the one at the first check
  // (the program, its libraries and the scene, about 130 MiB, before any grid is planned)
  if (input_limits().max_host_bytes != 0) {
    static const uint64_t base = vm_rss.value_or(0);
    const std::optional<uint64_t> work = vm_rss ? std::optional<uint64_t>(*vm_rss > base ? *vm_rss - base : 0) : std::nullopt;
    room = std::min(room, left(input_limits().max_host_bytes, work));
  }
  return room;
}

// A size for a message: MiB to two decimals (a 1.53 MiB file read "2 MiB": whole MiB were rounded
// up, an outside sweep), below 16 MiB with the bytes too, so that a file just over a small limit
// does not read "1 MiB, more than the limit of 1 MiB" (another)
static std::string mib(uint64_t bytes) {
  // Below a MiB, the bytes alone (a 2,418-byte file "held 1 MiB": an outside sweep)
  if (bytes < (uint64_t(1) << 20)) return std::to_string(bytes) + " bytes";
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.2f MiB", double(bytes) / double(uint64_t(1) << 20));
  return bytes >= (uint64_t(16) << 20) ? std::string(buf) : std::string(buf) + " (" + std::to_string(bytes) + " bytes)";
}

void require_host_memory(uint64_t bytes, const std::string& what, const std::string& advice) {
  const uint64_t room = host_memory_available();
  if (bytes <= room) return;
  const auto rss = read_number("/proc/self/status", "VmRSS:", 1024);
  // Sizes below 16 MiB with their bytes ("1 MiB, more than the 0 MiB available": an outside sweep),
  // the option named once
  // None left: say so ("more than the 0 bytes left" puzzled a reader: an outside sweep)
  throw Error(what + " need about " + mib(bytes) + " of host memory, " +
              (room > 0 ? "more than the " + mib(room) + " left" : std::string("and none is left")) +
              (input_limits().max_host_bytes ? " of --max-host-mib's " + mib(input_limits().max_host_bytes) +
                                                   " (what the grids and textures planned so far take counts)"
                                             : std::string()) +
              (rss ? " (this process holds " + mib(*rss) + ")" : "") + " (" + advice +
              (advice.find("--max-host-mib") == std::string::npos && !input_limits().max_host_bytes ? "; --max-host-mib"
                                                                                                    : "") +
              ")");
}

namespace {

// Opens `path` for reading after checking it is a regular file within the size bound; returns
// the descriptor (the caller closes it) and the size.
// The inputs read so far (guard_inputs): device and inode, and how they were named.
struct InputRecord {
  std::string path, what;
};
struct InputRegistry {
  std::mutex mutex;
  bool on = false;
  std::map<std::pair<dev_t, ino_t>, InputRecord> files;
};
InputRegistry& input_registry() {
  static InputRegistry r;
  return r;
}

void note_input(const struct stat& st, const std::string& path, const std::string& what) {
  InputRegistry& r = input_registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  if (r.on) r.files.try_emplace({st.st_dev, st.st_ino}, InputRecord{path, what});
}

int open_input(const std::string& path, const std::string& what, uint64_t& size) {
  const std::string head = "cannot open " + what + " '" + path + "': ";
  // O_NONBLOCK: opening a FIFO without a writer must not block; fstat then rejects it.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    const int e = errno;
    throw Error(head + (e == ENOENT ? std::string("no such file") : std::strerror(e)));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    throw Error(head + std::strerror(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    const char* kind = S_ISDIR(st.st_mode)    ? "a directory"
                       : S_ISFIFO(st.st_mode) ? "a FIFO"
                       : S_ISCHR(st.st_mode)  ? "a character device"
                       : S_ISBLK(st.st_mode)  ? "a block device"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                                              : "not a regular file";
    throw Error(head + "it is " + kind + ", not a regular file");
  }
  note_input(st, path, what);
  size = uint64_t(st.st_size);
  if (size > input_limits().max_file_bytes) {
    ::close(fd);
    throw Error(head + "it holds " + mib(size) + ", more than the limit of " + mib(input_limits().max_file_bytes) +
                " (--max-input-mib)");
  }
  return fd;
}

}  // namespace

std::string why_missing(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (fs::exists(st)) return "";
  if (!ec || ec == std::errc::no_such_file_or_directory) return "no such file";
  return ec.message();
}

bool is_folder(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

uint64_t check_input_file(const std::string& path, const std::string& what) {
  uint64_t size = 0;
  ::close(open_input(path, what, size));
  return size;
}

std::string read_input_file(const std::string& path, const std::string& what) {
  uint64_t size = 0;
  const int fd = open_input(path, what, size);
  std::string data;
  try {
    data.resize(size_t(size));
  } catch (const std::bad_alloc&) {
    ::close(fd);
    throw Error("cannot read " + what + " '" + path + "': out of memory for " + mib(size));
  }
  size_t got = 0;
  while (got < data.size()) {
    const ssize_t n = ::read(fd, data.data() + got, data.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      throw Error("cannot read " + what + " '" + path + "': " + std::strerror(e));
    }
    if (n == 0) break;  // the file shrank while it was read
    got += size_t(n);
  }
  ::close(fd);
  data.resize(got);
  return data;
}

void check_json_depth(std::string_view text, const std::string& where, uint32_t max_depth) {
  uint32_t depth = 0;
  bool in_string = false;
  size_t line = 1;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') ++line;
    if (in_string) {
      if (c == '\\') ++i;
      else if (c == '"') in_string = false;
      continue;
    }
    if (c == '"') in_string = true;
    else if (c == '[' || c == '{') {
      if (++depth > max_depth)
        throw Error(where + ":" + std::to_string(line) + ": JSON nests arrays and objects more than " +
                    std::to_string(max_depth) + " deep (the limit)");
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
}

std::string normalize_text(std::string text) {
  size_t start = 0;
  if (text.size() >= 3 && text.compare(0, 3, "\xEF\xBB\xBF") == 0) start = 3;
  std::string out;
  out.reserve(text.size() - start);
  for (size_t i = start; i < text.size(); ++i) {
    if (text[i] == '\r') {
      out.push_back('\n');
      if (i + 1 < text.size() && text[i + 1] == '\n') ++i;
    } else {
      out.push_back(text[i]);
    }
  }
  return out;
}

uint64_t checked_mul(uint64_t a, uint64_t b, const std::string& what) {
  uint64_t r = 0;
  if (__builtin_mul_overflow(a, b, &r))
    throw Error(what + ": " + std::to_string(a) + " x " + std::to_string(b) + " overflows 64 bits");
  return r;
}

namespace {

fs::path temp_sibling(const fs::path& path) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  // Same extension at the end: libraries that pick the format by name see the right one.
  std::string tag = ".tmp" + std::to_string(::getpid()) + path.extension().string();
  if (tag.size() > 64) tag = ".tmp" + std::to_string(::getpid());  // an extension longer than any format's
  std::string stem = path.filename().string();
  // Within the file system's name limit (255 bytes): a legal output name of 241 bytes and more
  // could not be written, its temporary's name too long (an outside sweep). Its first bytes then.
  const size_t room = 255 - 1 - tag.size();
  if (stem.size() > room) stem.resize(room);
  return dir / ("." + stem + tag);
}

// The temporary file being written, removed if SIGINT, SIGTERM or SIGHUP ends the process
// meanwhile (then the signal takes its default course): an interrupted run leaves the old output
// and nothing beside it. One at a time; its path in a fixed buffer, as a handler can only unlink.
char pending_tmp[4096];
volatile sig_atomic_t pending_set = 0;

extern "C" void remove_pending_and_reraise(int sig) {
  if (pending_set) ::unlink(pending_tmp);
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

struct PendingTemp {
  explicit PendingTemp(const fs::path& tmp) {
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
      struct sigaction old {};
      // Where the signal takes its default course; a handler the program set itself is left alone
      if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_DFL && !(old.sa_flags & SA_SIGINFO)) {
        struct sigaction sa {};
        sa.sa_handler = &remove_pending_and_reraise;
        sigemptyset(&sa.sa_mask);
        ::sigaction(sig, &sa, nullptr);
      }
    }
    const std::string p = tmp.string();
    if (p.size() < sizeof pending_tmp) {
      pending_set = 0;
      std::memcpy(pending_tmp, p.c_str(), p.size() + 1);
      pending_set = 1;
    }
  }
  ~PendingTemp() { pending_set = 0; }
  PendingTemp(const PendingTemp&) = delete;
  PendingTemp& operator=(const PendingTemp&) = delete;
};

// A temporary file in the system's temporary folder with `path`'s extension: for an output that
// is streamed (below), whose own folder (/dev) is no place for it.
fs::path temp_elsewhere(const fs::path& path) {
  std::error_code ec;
  fs::path dir = fs::temp_directory_path(ec);
  if (ec) dir = "/tmp";
  return dir / ("gridrt-" + std::to_string(::getpid()) + "-out" + path.extension().string());
}

[[noreturn]] void fail_write(const std::string& path, const std::string& what, const fs::path& tmp, int err,
                             const std::string& step) {
  ::unlink(tmp.c_str());  // errno of the failure was saved in `err` before this
  throw Error("cannot write " + what + " '" + path + "': " + step + ": " + std::strerror(err));
}

// Where an output goes. A regular file or a new name is replaced atomically (a temporary file
// beside it, renamed over it); a symbolic link is followed (its target is replaced, the link
// kept); a FIFO or a character device (/dev/stdout, /dev/null, a pipe) is streamed to, as the
// bytes of a complete file (the rename would put a regular file in its place, under /dev as
// root); anything else (a folder, a block device, a socket) is refused, named.
struct OutputTarget {
  fs::path path;
  bool stream = false;
  int fd = -1;  // the process's own descriptor the path names (/dev/stdout...), written directly
};

// The descriptor /dev/stdout, /dev/stderr, /dev/fd/N or /proc/self/fd/N names, else -1. Opened by
// its path these lead, through /proc, to whatever the descriptor holds: with the output
// redirected to a file (`>> log`), the file, which the rename would replace (the log's earlier
// lines gone) and a new open would overwrite from its start.
// Where the symbolic link `p` leads (its target, a relative one taken from p's folder); nothing
// where p is no link. `error`: set where the link cannot be read.
std::optional<fs::path> link_target(const fs::path& p, std::error_code& error) {
  struct stat lst {};
  if (::lstat(p.c_str(), &lst) != 0 || !S_ISLNK(lst.st_mode)) return std::nullopt;
  const fs::path target = fs::read_symlink(p, error);
  if (error) return std::nullopt;
  return target.is_absolute() ? target : p.parent_path() / target;
}

int own_descriptor(const std::string& path) {
  const std::string pid = std::to_string(::getpid());
  const std::string prefixes[] = {"/dev/fd/", "/proc/self/fd/", "/proc/thread-self/fd/", "/proc/" + pid + "/fd/"};
  // However spelled ("/dev//stdout", "/dev/./stdout") and through the user's own links to them
  fs::path p = fs::path(path).lexically_normal();
  for (int links = 0; links < 40; ++links) {
    const std::string s = p.string();
    if (s == "/dev/stdout") return 1;
    if (s == "/dev/stderr") return 2;
    for (const std::string& prefix : prefixes)
      if (s.size() > prefix.size() && s.compare(0, prefix.size(), prefix) == 0 && s.size() - prefix.size() <= 6 &&
          std::all_of(s.begin() + std::ptrdiff_t(prefix.size()), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
        return std::stoi(s.substr(prefix.size()));
    std::error_code ec;
    const std::optional<fs::path> next = link_target(p, ec);
    if (!next) return -1;
    p = next->lexically_normal();
  }
  return -1;
}

// A file's permission bits as `ls` and chmod take them: "0444".
std::string octal_mode(mode_t mode) {
  char text[8];
  std::snprintf(text, sizeof text, "%04o", unsigned(mode & 07777));
  return text;
}

OutputTarget resolve_output(const std::string& path, const std::string& what) {
  const std::string head = "cannot write " + what + " '" + path + "': ";
  if (const int fd = own_descriptor(path); fd >= 0) {
    if (::fcntl(fd, F_GETFD) < 0) throw Error(head + "the descriptor is not open");
    return {path, true, fd};
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {  // what the path leads to, links followed
    if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode)) return {path, true};  // opened through the links
    if (S_ISREG(st.st_mode)) {
      // A file nobody may write is not replaced, though the rename needs only its folder's
      // permission: a read-only (0444) output was replaced, its mode kept (an outside sweep). The
      // mode's bits are read as well as access(): as root access() allows every file
      if ((st.st_mode & 0222) == 0 || ::access(path.c_str(), W_OK) != 0)
        throw Error(head + "it is read-only (mode " + octal_mode(st.st_mode) +
                    "): an output replaces only a file it may write (chmod u+w it, or name another file)");
      struct stat lst {};
      if (::lstat(path.c_str(), &lst) != 0 || !S_ISLNK(lst.st_mode)) return {path, false};
      char* real = ::realpath(path.c_str(), nullptr);  // the file the links lead to is replaced
      if (!real) throw Error(head + std::strerror(errno));
      const fs::path target = real;
      std::free(real);
      return {target, false};
    }
    const char* kind = S_ISDIR(st.st_mode)    ? "a folder"
                       : S_ISBLK(st.st_mode)  ? "a block device"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                                              : "not a regular file";
    throw Error(head + "it is " + kind + " (outputs are regular files, FIFOs or character devices)");
  }
  if (errno != ENOENT) throw Error(head + std::strerror(errno));
  // Nothing there: a new file, or a dangling link whose target is created (as a shell's `>` does)
  fs::path p = path;
  for (int links = 0;; ++links) {
    std::error_code ec;
    const std::optional<fs::path> next = link_target(p, ec);
    if (ec) throw Error(head + "cannot read the symbolic link '" + p.string() + "': " + ec.message());
    if (!next) return {p, false};
    if (links >= 40) throw Error(head + "more than 40 symbolic links to follow");
    p = *next;
  }
}

// fsync + close of the descriptor; `verify(tmp)` where given; then rename tmp over path.
void finish(const std::string& path, const std::string& what, const fs::path& target, const fs::path& tmp, int fd,
            const std::function<void(const std::string& tmp)>& verify) {
  if (::fsync(fd) != 0) {
    const int e = errno;
    ::close(fd);
    fail_write(path, what, tmp, e, "fsync of the temporary file failed");
  }
  if (::close(fd) != 0) fail_write(path, what, tmp, errno, "close of the temporary file failed");
  if (verify) {
    try {
      verify(tmp.string());
    } catch (...) {
      ::unlink(tmp.c_str());
      throw;
    }
  }
  if (::rename(tmp.c_str(), target.c_str()) != 0)
    fail_write(path, what, tmp, errno, "rename of the temporary file failed");
}

// Every byte to `fd`, checked; the errno of a failure, else 0.
int write_all(int fd, std::string_view bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return n < 0 ? errno : EIO;
    done += size_t(n);
  }
  return 0;
}

// The bytes to `tmp` (created new), synced, verified and renamed over `target`.
void write_replacing(const std::string& path, const std::string& what, const fs::path& target, const fs::path& tmp,
                     std::string_view bytes, const std::function<void(const std::string& tmp)>& verify) {
  const PendingTemp pending(tmp);
  ::unlink(tmp.c_str());  // a leftover of an earlier process with the same id
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) {
    const int e = errno;
    throw Error("cannot write " + what + " '" + path + "': cannot create the temporary file '" + tmp.string() +
                "': " + std::strerror(e));
  }
  // A file replaced keeps its permissions (a 0600 file became 0644: an outside sweep)
  struct stat old {};
  if (::stat(target.c_str(), &old) == 0 && S_ISREG(old.st_mode)) (void)::fchmod(fd, old.st_mode & 07777);
  if (const int e = write_all(fd, bytes); e != 0) {
    ::close(fd);
    fail_write(path, what, tmp, e, "write failed");
  }
  finish(path, what, target, tmp, fd, verify);
}

// A FIFO or character device: the complete bytes, written in order, every write checked.
void write_stream(const std::string& path, const std::string& what, const OutputTarget& t, std::string_view bytes) {
  if (t.fd >= 0) {
    // The process's own standard output or error: after what it printed there, in order
    std::cout.flush();
    std::cerr.flush();
    std::fflush(nullptr);
    if (const int e = write_all(t.fd, bytes); e != 0)
      throw Error("cannot write " + what + " '" + path + "': write failed: " + std::strerror(e));
    return;
  }
  const fs::path& target = t.path;
  const int fd = ::open(target.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    const int e = errno;
    throw Error("cannot write " + what + " '" + path + "': " + std::strerror(e));
  }
  int e = write_all(fd, bytes);
  if (::close(fd) != 0 && e == 0) e = errno;
  if (e != 0) throw Error("cannot write " + what + " '" + path + "': write failed: " + std::strerror(e));
}

// The bytes of a temporary file written by a library, which is then removed.
std::string slurp_and_remove(const std::string& path, const std::string& what, const fs::path& tmp) {
  std::string bytes;
  const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail_write(path, what, tmp, errno, "cannot reopen the temporary file");
  char buf[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      fail_write(path, what, tmp, e, "cannot read the temporary file back");
    }
    if (n == 0) break;
    bytes.append(buf, size_t(n));
  }
  ::close(fd);
  ::unlink(tmp.c_str());
  return bytes;
}

}  // namespace

void guard_inputs(bool on) {
  InputRegistry& r = input_registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  r.on = on;
}

namespace {
// An output over a file this run read (guard_inputs): refused, before a byte is written.
void refuse_input_target(const OutputTarget& t, const std::string& path, const std::string& what) {
  if (t.stream) return;
  struct stat st {};
  if (::stat(t.path.c_str(), &st) != 0) return;
  InputRegistry& r = input_registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  const auto it = r.files.find({st.st_dev, st.st_ino});
  if (it != r.files.end())
    throw Error("cannot write " + what + " '" + path + "': it is the " + it->second.what + " '" + it->second.path +
                "' this run read; an output may not replace an input: name another file");
}
}  // namespace

void check_output_allowed(const std::string& path, const std::string& what) {
  refuse_input_target(resolve_output(path, what), path, what);
}

void write_file_atomically(const std::string& path, const std::string& what, std::string_view bytes,
                           const std::function<void(const std::string& tmp)>& verify) {
  const OutputTarget t = resolve_output(path, what);
  refuse_input_target(t, path, what);
  if (!t.stream) return write_replacing(path, what, t.path, temp_sibling(t.path), bytes, verify);
  if (verify) {  // checked on a file of its own before a byte goes out
    const fs::path tmp = temp_elsewhere(t.path);
    write_replacing(path, what, tmp, tmp, bytes, verify);
    ::unlink(tmp.c_str());
  }
  write_stream(path, what, t, bytes);
}

void write_file_atomically(const std::string& path, const std::string& what,
                           const std::function<void(const std::string& tmp)>& write) {
  const OutputTarget t = resolve_output(path, what);
  refuse_input_target(t, path, what);
  const fs::path tmp = t.stream ? temp_elsewhere(t.path) : temp_sibling(t.path);
  const PendingTemp pending(tmp);
  ::unlink(tmp.c_str());
  try {
    write(tmp.string());
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
  if (t.stream) return write_stream(path, what, t, slurp_and_remove(path, what, tmp));
  const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail_write(path, what, tmp, errno, "cannot reopen the temporary file");
  finish(path, what, t.path, tmp, fd, nullptr);
}

bool is_stream_output(const std::string& path) {
  if (own_descriptor(path) >= 0) return true;
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode));
}

namespace {
// The path with its links followed, a dangling one's too (weakly_canonical stops at a link to a
// file not made yet), as absolute and normal.
fs::path links_followed(const std::string& path) {
  std::error_code ec;
  fs::path p = fs::absolute(path, ec).lexically_normal();
  for (int links = 0; links < 40; ++links) {
    const std::optional<fs::path> next = link_target(p, ec);
    if (!next) break;
    p = next->lexically_normal();
  }
  return fs::weakly_canonical(p, ec).lexically_normal();
}
}  // namespace

bool names_same_file(const std::string& a, const std::string& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) {
    const bool same = fs::equivalent(a, b, ec);
    if (!ec) return same;
  }
  return links_followed(a) == links_followed(b);
}

namespace {
// The length of the well-formed UTF-8 sequence at s[i], 0 if none starts there.
size_t utf8_sequence(std::string_view s, size_t i) {
  const auto b = [&](size_t k) { return uint8_t(s[k]); };
  const uint8_t c = b(i);
  const size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
  if (n == 0 || i + n > s.size()) return 0;
  for (size_t k = 1; k < n; ++k)
    if ((b(i + k) >> 6) != 0x2) return 0;
  if (n == 2 && c < 0xC2) return 0;  // overlong
  if (n == 3 && ((c == 0xE0 && b(i + 1) < 0xA0) || (c == 0xED && b(i + 1) >= 0xA0))) return 0;  // overlong, surrogate
  if (n == 4 && ((c == 0xF0 && b(i + 1) < 0x90) || (c == 0xF4 && b(i + 1) >= 0x90) || c > 0xF4)) return 0;
  return n;
}
}  // namespace

bool is_utf8(std::string_view s) {
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_sequence(s, i);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

std::string to_utf8(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_sequence(s, i);
    if (n == 0) {
      out += "\xEF\xBF\xBD";
      ++i;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
  }
  return out;
}

}  // namespace gridrt
