// explain_format.h: an ExplainRecord for people: the full account (every event numbered, floats
// in decimal and hex bits), a brief one (one line an event, decimal, runs of empty cells folded),
// JSON (the records as they are, with names), and two records side by side: the reference's and
// the shader's, aligned over their events' keys, the divergent events and their differing fields
// marked, the segment or cell each belongs to kept.
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gridrt/common/scene.h"
#include "gridrt/common/shared/explain.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/tracer.h"
#include "gridrt/plan/records.h"

namespace gridrt::plan {

// What an explain calls the scene's instances: the instance's name, else its mesh's.
struct ExplainNames {
  std::vector<std::string> instances;
  static ExplainNames of(const Scene& scene);
};

struct ExplainFormat {
  bool brief = false;                  // one line an event, no hex, empty cells folded
  const ExplainNames* names = nullptr;  // null: instances by number only
};

// "ray", "setup", "cell", "slot", "test", ... (kEv*)
const char* event_kind_name(uint32_t kind);
// The code of an event in words: "accepted", "outside-u", "left-grid", ... ("" where the kind has
// no code)
std::string event_code_name(uint32_t kind, uint32_t code);

// What each field of an event of `kind` means ("" where the kind leaves it unused), in the
// order kind, code, ref, step, cell, slot, f0.x .. f0.w, f1.x .. f1.w; `exact`: the exact
// traversal's kEvCell.
struct EventField {
  const char* field;  // "code", "ref", "f0.x", ...
  const char* name;   // what it holds, "" when unused
};
std::vector<EventField> event_fields(uint32_t kind, bool exact);

// A reference as words: `instance 3 "floor", triangle 12` (full mode adds its hex word).
std::string reference_text(uint32_t ref, const ExplainFormat& format);
// The grid an explain ran on: resolution, cell size, origin, capacity, traversal, insertion,
// spill, gap-fill.
std::string grid_text(const shared::GridParams& g, const ExplainFormat& format);

// Event i of `rec` as text: full mode, its lines (the first starts with the event's words, the
// others are indented details); brief mode, one line.
std::vector<std::string> event_lines(const ExplainRecord& rec, size_t i, const ExplainFormat& format);
// Event i in one line without hex (the brief form; side-by-side rows use it too).
std::string event_summary(const ExplainRecord& rec, size_t i, const ExplainFormat& format);
// The whole record: the grid, every event numbered "#n", the counters.
std::string explain_text(const ExplainRecord& rec, const ExplainFormat& format);
// The record as JSON: the ray, the grid parameters, every event (its raw fields, float bits in
// hex, the kind's and code's names, the fields by name, instances by number and name), the hit.
nlohmann::json explain_json(const ExplainRecord& rec, const ExplainFormat& format);

// A ray from text: "ox,oy,oz,dx,dy,dz[,tmin,tmax[,launch_ref]]", floats in decimal or C99 hex
// (0x1.8p+1, inf, nan), launch_ref a number, 0x hex, INSTANCE:TRIANGLE or "none"; tmin 0, tmax
// +inf, no launch reference and a zero launch normal where not given. Error on anything else.
Ray parse_ray(const std::string& text);
// The rays of a file: one a line in parse_ray's syntax, # comments and blank lines skipped; errors
// name the file and line.
std::vector<Ray> read_ray_file(const std::string& path);

// The visit event i belongs to: the last kEvCell or kEvCellSkipped at or before it (npos: before
// the first visit).
inline constexpr size_t kNoEvent = size_t(-1);
size_t visit_of(const ExplainRecord& rec, size_t i);
// "segment 12, cell (3, 4, 5) (event #50)" or "step 7, cell ..." or "before the first cell".
std::string visit_text(const ExplainRecord& rec, size_t i);

// Two event lists aligned: rows pair the events of `a` and `b` that take the same place in the
// traversal (a longest common subsequence over the keys (kind, step, cell, slot); the ray, setup
// and final events by kind alone), the unpaired events between two paired ones are set side by
// side in order, the rest stand alone (kNoEvent on the other side).
struct EventAlignment {
  struct Row {
    size_t a = kNoEvent, b = kNoEvent;
    bool same = false;  // both present and equal bit for bit
  };
  std::vector<Row> rows;
  size_t first_divergence = kNoEvent;  // the first row that is not `same`
  size_t differing_rows() const;
};
EventAlignment align_events(std::span<const shared::ExplainEvent> a, std::span<const shared::ExplainEvent> b);
// The fields of two events that differ in bits, as "field (name)", e.g. "f0.w (t*|det|)".
std::vector<std::string> differing_fields(const shared::ExplainEvent& a, const shared::ExplainEvent& b, bool exact);
// The two hit records' fields that differ in bits ("t", "instance", ...).
std::vector<std::string> differing_hit_fields(const Hit& a, const Hit& b);

// The reference's record (`want`) and the shader's (`got`) side by side: "identical" where they
// agree bit for bit; else where they part (the event numbers on both sides, the segment or cell
// the event belongs to, the fields that differ), then the aligned rows from the start of that
// visit to the end (identical rows before it folded; in brief mode runs of identical rows after
// it folded too), each differing row followed by its differing fields with both values, and the
// two hits. `labels`: the names of the two columns.
std::string divergence_text(const ExplainRecord& want, const ExplainRecord& got, const ExplainFormat& format,
                            const std::string& want_label = "reference", const std::string& got_label = "shader");
// The alignment as JSON: rows [a, b, same] (null for a missing side), the first divergence with
// its visit and differing fields.
nlohmann::json alignment_json(const ExplainRecord& want, const ExplainRecord& got, const EventAlignment& alignment);

}  // namespace gridrt::plan
