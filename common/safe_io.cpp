#include "gridrt/common/safe_io.h"

#include <cerrno>
#include <cstring>
#include <filesystem>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace gridrt {
namespace fs = std::filesystem;

InputLimits& input_limits() {
  static InputLimits limits;
  return limits;
}

namespace {

std::string mib(uint64_t bytes) { return std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB"; }

// Opens `path` for reading after checking it is a regular file within the size bound; returns
// the descriptor (the caller closes it) and the size.
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
  return dir / ("." + path.filename().string() + ".tmp" + std::to_string(::getpid()) + path.extension().string());
}

[[noreturn]] void fail_write(const std::string& path, const std::string& what, const fs::path& tmp, int err,
                             const std::string& step) {
  ::unlink(tmp.c_str());  // errno of the failure was saved in `err` before this
  throw Error("cannot write " + what + " '" + path + "': " + step + ": " + std::strerror(err));
}

// fsync + close of the descriptor; then rename tmp over path.
void finish(const std::string& path, const std::string& what, const fs::path& tmp, int fd) {
  if (::fsync(fd) != 0) {
    const int e = errno;
    ::close(fd);
    fail_write(path, what, tmp, e, "fsync of the temporary file failed");
  }
  if (::close(fd) != 0) fail_write(path, what, tmp, errno, "close of the temporary file failed");
  if (::rename(tmp.c_str(), path.c_str()) != 0)
    fail_write(path, what, tmp, errno, "rename of the temporary file failed");
}

}  // namespace

void write_file_atomically(const std::string& path, const std::string& what, std::string_view bytes) {
  const fs::path tmp = temp_sibling(path);
  ::unlink(tmp.c_str());  // a leftover of an earlier process with the same id
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) {
    const int e = errno;
    throw Error("cannot write " + what + " '" + path + "': cannot create the temporary file '" + tmp.string() +
                "': " + std::strerror(e));
  }
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = n < 0 ? errno : EIO;
      ::close(fd);
      fail_write(path, what, tmp, e, "write failed");
    }
    done += size_t(n);
  }
  finish(path, what, tmp, fd);
}

void write_file_atomically(const std::string& path, const std::string& what,
                           const std::function<void(const std::string& tmp)>& write) {
  const fs::path tmp = temp_sibling(path);
  ::unlink(tmp.c_str());
  try {
    write(tmp.string());
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
  const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail_write(path, what, tmp, errno, "cannot reopen the temporary file");
  finish(path, what, tmp, fd);
}

}  // namespace gridrt
