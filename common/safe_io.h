// safe_io.h: bounded input and atomic output, for every file the tool reads or writes.
//
// Input: only regular files are read (a directory, a FIFO or a device such as /dev/zero is an
// Error naming it), and only up to a size bound. Everything that sizes an allocation from a file
// (element counts, image dimensions, nesting depth, face sizes) is checked against InputLimits
// with overflow-safe arithmetic before the allocation.
//
// Output: write_file_atomically writes a temporary file in the target's folder, checks every
// write, fsyncs and closes it, and renames it over the target only when all of that succeeded;
// on failure the temporary file is removed and the Error names the target and the system's
// reason (errno is kept across the clean-up). An existing file is replaced only by a complete one.
// A symbolic link is followed (its target replaced, the link kept); a FIFO or a character device
// (/dev/stdout, a pipe) is written to in place, the complete bytes, every write checked (/dev/full
// fails with the system's reason); a folder, block device or socket is refused, named.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "gridrt/common/scene.h"

namespace gridrt {

// Resource limits on what a file may make the tool allocate. Process-wide; the command line
// sets them (--max-texture-pixels, --max-triangles, --max-input-mib), the defaults are safe.
struct InputLimits {
  uint64_t max_file_bytes = uint64_t(4) << 30;      // any one input file
  uint64_t max_texture_pixels = uint64_t(1) << 26;  // any one texture (67 Mpixel, 256 MiB RGBA8)
  uint64_t max_triangles = uint64_t(1) << 25;       // a scene, over all instances (33.5 M)
  uint64_t max_vertices = uint64_t(1) << 26;        // a scene's meshes together
  uint32_t max_face_vertices = 1024;                // one OBJ polygon (triangulated as a fan)
  uint32_t max_json_depth = 256;                    // nesting of arrays and objects (JSON, glTF)
  uint32_t max_node_depth = 1000;                   // glTF node hierarchy
  uint64_t max_host_bytes = 0;  // the grid build's host memory (--max-host-mib); 0: what the machine has free

};
InputLimits& input_limits();

// The host memory this process may still take, in bytes: the least of the machine's available
// memory (/proc/meminfo's MemAvailable), its cgroup's room (memory.max less memory.current), the
// address-space and data limits (ulimit -v, -d) less this process's address space and data
// segment, and --max-host-mib where it is set less what its resident set has grown by since the
// first call (/proc/self/status: the earlier grids of the same verb; the program, its libraries
// and the scene, held before any grid is planned, are not counted). UINT64_MAX where none can be
// read.
uint64_t host_memory_available();

// Error, before anything is allocated, when `bytes` exceed host_memory_available(): "<what> need
// about X MiB of host memory, more than the Y MiB available (<advice>; --max-host-mib)". For
// sizes an option asks for (a resolution, a memory budget), so that an impossible request fails at
// once with its reason, not after minutes of swapping or as an anonymous allocation failure.
void require_host_memory(uint64_t bytes, const std::string& what, const std::string& advice);

// The bytes of the regular file at `path`. Error ("cannot open <what> '<path>': ...") when it is
// missing, not a regular file (directory, FIFO, device), larger than max_file_bytes or unreadable.
std::string read_input_file(const std::string& path, const std::string& what);

// Looking a path up without throwing: "" when something exists at `path`, else why not ("no
// such file", or the system's reason: "File name too long", "Permission denied", ...).
// std::filesystem::exists throws on a name the system cannot look up; files named inside input
// (a scene's meshes, an OBJ's material libraries) go through this instead.
std::string why_missing(const std::string& path);

// Whether `path` is a folder; false (never a throw) when it cannot be looked up.
bool is_folder(const std::string& path);

// The same checks without reading: for files a library opens itself (images through
// OpenImageIO). Returns the file's size.
uint64_t check_input_file(const std::string& path, const std::string& what);

// Error unless `text` nests arrays and objects at most `max_depth` deep (strings skipped). Run
// before a recursive JSON parser sees the text, so that deep nesting cannot exhaust the stack.
void check_json_depth(std::string_view text, const std::string& where, uint32_t max_depth);

// The one line-break rule of the text formats: CR LF, a bare CR and LF all end a line. Returns
// the text with every line break as LF and a leading UTF-8 byte-order mark removed.
std::string normalize_text(std::string text);

// a * b, or Error("<what>: ... overflows") when the product does not fit 64 bits.
uint64_t checked_mul(uint64_t a, uint64_t b, const std::string& what);

// Whether `s` is well-formed UTF-8 (no overlong forms, surrogates or code points past U+10FFFF):
// what JSON and XML readers accept.
bool is_utf8(std::string_view s);
// `s` with every byte that is not part of a well-formed UTF-8 sequence as U+FFFD.
std::string to_utf8(std::string_view s);

// From now on, remember every input file this process reads (check_input_file, read_input_file:
// the scene, its meshes, materials, textures, ray files) and refuse, in write_file_atomically, an
// output that would replace one of them (however its path is spelled: the same device and inode).
// The tool turns it on; a library's caller may.
void guard_inputs(bool on);
// Refuses now (throws Error, as write_file_atomically would) an output `path` that would replace an
// input this run read (guard_inputs), or that cannot be named as an output: for a verb that writes
// several files, every one is checked before the first is written, so that a refused one leaves the
// others as they were.
void check_output_allowed(const std::string& path, const std::string& what);

// Whether two paths name one file: the same file where both exist (links followed, however
// spelled), else the same absolute path once "." and ".." and the links of its existing part are
// resolved ("a.json" and "$PWD/a.json", "./a.svg" and "a.svg", "sub/../a" and "a").
bool names_same_file(const std::string& a, const std::string& b);
// Whether an output path is a stream (the process's own descriptor however spelled, a character
// device, a FIFO): written in order, replacing nothing, so two outputs may share it.
bool is_stream_output(const std::string& path);

// Write `bytes` to `path` atomically (see above). `what` names the kind of file in messages
// ("image", "scene cache", "CSV table"). `verify(tmp)`, where given, checks the written
// temporary file before it replaces anything (it throws to refuse it; a streamed output is
// verified on a temporary file of its own before a byte goes out).
void write_file_atomically(const std::string& path, const std::string& what, std::string_view bytes,
                           const std::function<void(const std::string& tmp)>& verify = nullptr);

// For writers that insist on a file name: `write(tmp)` writes the temporary file (and throws on
// failure); then it is synced and renamed as above. A writer that does not report errors must
// not be used with this (the caller verifies, see image_io.cpp).
void write_file_atomically(const std::string& path, const std::string& what,
                           const std::function<void(const std::string& tmp)>& write);

}  // namespace gridrt
