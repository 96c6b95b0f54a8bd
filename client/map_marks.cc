#include "client/map_marks.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string_view>
#include <utility>

#include "base/file.h"
#include "base/limits.h"
#include "base/validate.h"

namespace bistable {
namespace {

constexpr size_t kShownBytes = 60;  // of a mark's text in a message

// The code point at s[*i], *i moved past it; -1 for a byte that does not start valid UTF-8 (overlong
// forms, surrogates and values beyond U+10FFFF included), *i moved past that byte alone.
long NextCodePoint(const std::string& s, size_t* i) {
  const unsigned char c = static_cast<unsigned char>(s[*i]);
  const size_t len = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : (c >> 3) == 30 ? 4 : 0;
  if (len == 0 || *i + len > s.size()) return ++*i, -1;
  long cp = len == 1 ? c : c & (0x7f >> len);
  for (size_t k = 1; k < len; ++k) {
    const unsigned char b = static_cast<unsigned char>(s[*i + k]);
    if ((b & 0xC0) != 0x80) return ++*i, -1;
    cp = (cp << 6) | (b & 0x3f);
  }
  constexpr long kMin[] = {0, 0, 0x80, 0x800, 0x10000};
  if (cp < kMin[len] || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return ++*i, -1;
  *i += len;
  return cp;
}

// Code points a label may not hold: C0 and C1 controls and DEL (a newline would end gnuplot's line, others
// rewrite a terminal), line and paragraph separators, bidirectional controls and the byte-order mark (they
// change how the text around them reads).
bool Unprintable(long cp) {
  return cp < 0x20 || (cp >= 0x7f && cp <= 0x9f) || cp == 0x2028 || cp == 0x2029 || cp == 0x200e || cp == 0x200f ||
         (cp >= 0x202a && cp <= 0x202e) || (cp >= 0x2066 && cp <= 0x2069) || cp == 0xfeff;
}

// `s` for a message: printable UTF-8 as it is, any other byte and backslash as \xNN, at most kShownBytes.
std::string Shown(const std::string& s) {
  std::string out;
  size_t i = 0;
  while (i < s.size() && out.size() < kShownBytes) {
    const size_t start = i;
    const long cp = NextCodePoint(s, &i);
    if (cp >= 0 && !Unprintable(cp) && cp != '\\') {
      out.append(s, start, i - start);
      continue;
    }
    for (size_t k = start; k < i; ++k) {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02x", static_cast<unsigned char>(s[k]));
      out += b;
    }
  }
  if (i < s.size()) out += "...";
  return out;
}

std::string Trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

StatusOr<double> MarkNumber(const std::string& text, const std::string& which, const MapMark& m) {
  const std::string t = Trim(text);
  char* end = nullptr;
  const double v = t.empty() ? NAN : std::strtod(t.c_str(), &end);
  if (t.empty() || end != t.c_str() + t.size() || !std::isfinite(v))
    return Status::InvalidArgument(
        m.field, m.origin + ": " + which + " = '" + Shown(t) + "' violates " + which + " a finite number");
  return v;
}

// A label: printable UTF-8, at most kMaxMarkLabelChars characters.
Status CheckLabel(const MapMark& m) {
  const std::string bound = "label <= " + std::to_string(limits::kMaxMarkLabelChars) + " characters";
  size_t i = 0, chars = 0;
  while (i < m.label.size()) {
    const long cp = NextCodePoint(m.label, &i);
    ++chars;
    if (chars > limits::kMaxMarkLabelChars)
      return Status::InvalidArgument(m.field, m.origin + ": the label is longer than " +
                                                  std::to_string(limits::kMaxMarkLabelChars) +
                                                  " characters (violates " + bound + ")");
    if (cp < 0)
      return Status::InvalidArgument(m.field, m.origin + ": character " + std::to_string(chars) +
                                                  " of the label is not UTF-8 (violates label = printable UTF-8 text)");
    if (Unprintable(cp)) {
      char u[24];
      std::snprintf(u, sizeof u, "U+%04lX", cp);
      return Status::InvalidArgument(m.field, m.origin + ": character " + std::to_string(chars) + " of the label is " +
                                                  u +
                                                  ", a control or layout character (violates label = one line of "
                                                  "printable text)");
    }
  }
  return Status::Ok();
}

}  // namespace

StatusOr<MapMark> ParseMark(const std::string& text, const std::string& field, const std::string& origin) {
  MapMark m;
  m.field = field;
  m.origin = origin;
  const size_t c1 = text.find(','), c2 = c1 == std::string::npos ? c1 : text.find(',', c1 + 1);
  if (c2 == std::string::npos)
    return Status::InvalidArgument(field, origin +
                                              " violates X,Y,LABEL (the value on the horizontal axis, the value on the "
                                              "vertical axis and the label, separated by commas)");
  auto x = MarkNumber(text.substr(0, c1), "X", m);
  if (!x.ok()) return x.status();
  auto y = MarkNumber(text.substr(c1 + 1, c2 - c1 - 1), "Y", m);
  if (!y.ok()) return y.status();
  m.x = *x, m.y = *y;
  std::string label = Trim(text.substr(c2 + 1));
  if (label.size() >= 2 && label.front() == '"' && label.back() == '"') {  // CSV quoting: "" is one quote
    std::string inner;
    for (size_t i = 1; i + 1 < label.size(); ++i) {
      inner += label[i];
      if (label[i] == '"' && label[i + 1] == '"' && i + 2 < label.size()) ++i;
    }
    label = inner;
  }
  m.label = std::move(label);
  BISTABLE_RETURN_IF_ERROR(CheckLabel(m));
  return m;
}

StatusOr<std::vector<MapMark>> ParseMarks(const std::vector<std::string>& marks, const std::string& file) {
  std::vector<MapMark> out;
  const auto too_many = [](const std::string& field, const std::string& origin) {
    return Status::InvalidArgument(
        field, "more than " + std::to_string(limits::kMaxMapMarks) + " marks (at " + origin +
                   "): --mark and --marks together violate marks <= " + std::to_string(limits::kMaxMapMarks));
  };
  for (const std::string& text : marks) {
    const std::string origin = "--mark '" + Shown(text) + "'";
    if (out.size() >= static_cast<size_t>(limits::kMaxMapMarks)) return too_many("mark", origin);
    auto m = ParseMark(text, "mark", origin);
    if (!m.ok()) return m.status();
    out.push_back(std::move(*m));
  }
  if (file.empty()) return out;
  auto bytes = ReadTextFile(file, "marks", limits::kMaxMarksFileBytes);
  if (!bytes.ok()) return bytes.status();
  std::string_view rest(*bytes);
  if (rest.substr(0, 3) == "\xef\xbb\xbf") rest.remove_prefix(3);  // a UTF-8 byte-order mark
  bool first_row = true;
  for (long line_no = 1; !rest.empty(); ++line_no) {
    const size_t nl = rest.find('\n');
    std::string line(rest.substr(0, nl));
    rest.remove_prefix(nl == std::string_view::npos ? rest.size() : nl + 1);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    if (std::exchange(first_row, false)) {
      std::string header;
      for (char c : trimmed)
        if (c != ' ' && c != '\t') header += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      if (header == "x,y,label") continue;
    }
    const std::string origin = "--marks '" + Shown(file) + "' line " + std::to_string(line_no);
    if (out.size() >= static_cast<size_t>(limits::kMaxMapMarks)) return too_many("marks", origin);
    auto m = ParseMark(line, "marks", origin);
    if (!m.ok()) return m.status();
    out.push_back(std::move(*m));
  }
  return out;
}

Status AddMarks(const std::vector<MapMark>& marks, PlotData* d) {
  if (marks.empty()) return Status::Ok();
  const MapMark& first = marks.front();
  if (d->axis_values.size() != 2 || d->axis_names.size() != 2) {
    std::string names;
    for (const std::string& n : d->axis_names) names += (names.empty() ? "" : ", ") + n;
    return Status::InvalidArgument(
        first.field, "--" + first.field + " draws on a heatmap over two free axes; this figure has " +
                         std::to_string(d->axis_names.size()) + " (" + names +
                         "): leave a second axis free (do not fix it with --at), or leave out --mark/--marks");
  }
  const std::string which_axes =
      "X is on the horizontal axis (" + d->axis_names[1] + "), Y on the vertical (" + d->axis_names[0] + ")";
  for (const MapMark& m : marks) {
    for (const size_t k : {size_t{1}, size_t{0}}) {  // axis 1 is drawn horizontally, axis 0 vertically
      const double v = k == 1 ? m.x : m.y;
      const std::vector<double>& grid = d->axis_values[k];
      const auto [lo, hi] = HeatmapAxisRange(grid);
      const double slack = 1e-9 * (hi - lo);  // an edge typed as printed (0.6) is inside however it rounds
      if (grid.empty() || (v >= lo - slack && v <= hi + slack)) continue;
      return Status::InvalidArgument(m.field, m.origin + ": " + (k == 1 ? "X = " : "Y = ") + FormatNumber(v) +
                                                  " is outside the figure's " + (k == 1 ? "horizontal" : "vertical") +
                                                  " axis " + d->axis_names[k] + ", drawn from " + FormatNumber(lo) +
                                                  " to " + FormatNumber(hi) + " (its grid values " +
                                                  FormatNumber(grid.front()) + " to " + FormatNumber(grid.back()) +
                                                  " and half a grid step beyond); " + which_axes);
    }
    d->marks.push_back({m.x, m.y, m.label});
  }
  return Status::Ok();
}

}  // namespace bistable
