#include "identify/record.h"

#include <charconv>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string_view>
#include <tuple>

#include "base/file.h"
#include "base/limits.h"
#include "base/names.h"
#include "base/validate.h"

namespace bistable {
namespace {

// ---- lines and cells ------------------------------------------------------------------------------

bool Blank(char ch, char sep) { return ch == ' ' || (ch == '\t' && sep != '\t'); }

// `line` split at `sep` outside double quotes, each cell trimmed of blanks; a quoted cell loses its
// quotes ("" inside is one "). false with *error (naming the 1-based column) when a quote is not
// closed on the line or text follows a closing quote.
bool SplitLine(std::string_view line, char sep, std::vector<std::string>* cells, std::string* error) {
  cells->clear();
  size_t i = 0;
  const size_t n = line.size();
  for (;;) {
    while (i < n && Blank(line[i], sep)) ++i;
    std::string cell;
    if (i < n && line[i] == '"') {
      for (++i;; ++i) {
        if (i >= n)
          return *error = "column " + std::to_string(cells->size() + 1) + ": a quote is not closed on its line", false;
        if (line[i] != '"') {
          cell += line[i];
        } else if (i + 1 < n && line[i + 1] == '"') {
          cell += '"', ++i;
        } else {
          ++i;
          break;
        }
      }
      while (i < n && Blank(line[i], sep)) ++i;
      if (i < n && line[i] != sep)
        return *error = "column " + std::to_string(cells->size() + 1) + ": text after the closing quote", false;
    } else {
      const size_t end = std::min(line.find(sep, i), n);
      size_t e = end;
      while (e > i && Blank(line[e - 1], sep)) --e;
      cell.assign(line.substr(i, e - i));
      i = end;
    }
    cells->push_back(std::move(cell));
    if (i >= n) return true;
    ++i;  // past the separator
  }
}

// How often `sep` occurs in `line` outside double quotes.
int CountOutsideQuotes(std::string_view line, char sep) {
  int count = 0;
  bool quoted = false;
  for (char ch : line) {
    if (ch == '"')
      quoted = !quoted;
    else if (ch == sep && !quoted)
      ++count;
  }
  return count;
}

std::string SeparatorName(char sep) { return sep == '\t' ? "tab" : std::string("'") + sep + "'"; }

// A cell as a number: what std::from_chars reads (no inf, nan or hex), with an optional leading '+',
// and with a decimal comma ("0,25": one comma, no point) where the separator is not a comma.
bool ParseNumber(const std::string& cell, bool decimal_comma, double* v) {
  std::string_view s = cell;
  if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  std::string copy;
  if (decimal_comma && s.find(',') != std::string_view::npos) {
    if (s.find(',') != s.rfind(',') || s.find('.') != std::string_view::npos) return false;
    copy.assign(s);
    copy[copy.find(',')] = '.';
    s = copy;
  }
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), *v);
  return ec == std::errc() && p == s.data() + s.size() && !s.empty() && std::isfinite(*v);
}

// ---- header names and units -----------------------------------------------------------------------

struct HeaderCell {
  std::string text;  // as in the file (unquoted)
  std::string name;  // without a unit suffix: "t [s]" → "t", "x0 (mm)" → "x0"
  std::string unit;  // "s", "mm"; "" without a suffix
};

HeaderCell ParseHeaderCell(const std::string& text) {
  HeaderCell h{text, text, ""};
  if (text.size() < 3) return h;
  const char close = text.back();
  if (close != ']' && close != ')') return h;
  const size_t open = text.rfind(close == ']' ? '[' : '(');
  if (open == std::string::npos || open == 0) return h;
  std::string name = text.substr(0, open), unit = text.substr(open + 1, text.size() - open - 2);
  while (!name.empty() && (name.back() == ' ' || name.back() == '\t')) name.pop_back();
  while (!unit.empty() && unit.back() == ' ') unit.pop_back();
  while (!unit.empty() && unit.front() == ' ') unit.erase(0, 1);
  if (name.empty() || unit.empty()) return h;
  h.name = name;
  h.unit = unit;
  return h;
}

enum class Quantity { kNone, kTime, kLength, kVelocity, kAcceleration, kForce, kVoltage };

const char* QuantityName(Quantity q) {
  switch (q) {
    case Quantity::kTime:
      return "time";
    case Quantity::kLength:
      return "length";
    case Quantity::kVelocity:
      return "velocity";
    case Quantity::kAcceleration:
      return "acceleration";
    case Quantity::kForce:
      return "force";
    case Quantity::kVoltage:
      return "voltage";
    case Quantity::kNone:
      break;
  }
  return "other";
}

struct UnitInfo {
  const char* name;
  Quantity quantity;
  double to_si;
};

// The units a header may give, with their factor to SI. "µ" is accepted as MICRO SIGN (U+00B5) and
// GREEK SMALL LETTER MU (U+03BC); g is standard gravity.
constexpr UnitInfo kUnits[] = {
    {"s", Quantity::kTime, 1},
    {"ms", Quantity::kTime, 1e-3},
    {"us", Quantity::kTime, 1e-6},
    {"\xc2\xb5s", Quantity::kTime, 1e-6},
    {"\xce\xbcs", Quantity::kTime, 1e-6},
    {"ns", Quantity::kTime, 1e-9},
    {"m", Quantity::kLength, 1},
    {"cm", Quantity::kLength, 1e-2},
    {"mm", Quantity::kLength, 1e-3},
    {"um", Quantity::kLength, 1e-6},
    {"\xc2\xb5m", Quantity::kLength, 1e-6},
    {"\xce\xbcm", Quantity::kLength, 1e-6},
    {"nm", Quantity::kLength, 1e-9},
    {"m/s", Quantity::kVelocity, 1},
    {"cm/s", Quantity::kVelocity, 1e-2},
    {"mm/s", Quantity::kVelocity, 1e-3},
    {"um/s", Quantity::kVelocity, 1e-6},
    {"\xc2\xb5m/s", Quantity::kVelocity, 1e-6},
    {"\xce\xbcm/s", Quantity::kVelocity, 1e-6},
    {"m/s^2", Quantity::kAcceleration, 1},
    {"m/s\xc2\xb2", Quantity::kAcceleration, 1},
    {"m/s2", Quantity::kAcceleration, 1},
    {"mm/s^2", Quantity::kAcceleration, 1e-3},
    {"mm/s\xc2\xb2", Quantity::kAcceleration, 1e-3},
    {"mm/s2", Quantity::kAcceleration, 1e-3},
    {"cm/s^2", Quantity::kAcceleration, 1e-2},
    {"cm/s\xc2\xb2", Quantity::kAcceleration, 1e-2},
    {"cm/s2", Quantity::kAcceleration, 1e-2},
    {"g", Quantity::kAcceleration, 9.80665},
    {"N", Quantity::kForce, 1},
    {"mN", Quantity::kForce, 1e-3},
    {"kN", Quantity::kForce, 1e3},
    {"V", Quantity::kVoltage, 1},
    {"mV", Quantity::kVoltage, 1e-3},
    {"uV", Quantity::kVoltage, 1e-6},
    {"\xc2\xb5V", Quantity::kVoltage, 1e-6},
    {"kV", Quantity::kVoltage, 1e3},
};

const UnitInfo* FindUnit(const std::string& unit) {
  for (const UnitInfo& u : kUnits)
    if (unit == u.name) return &u;
  return nullptr;
}

std::vector<std::string> UnitNames(Quantity q) {
  std::vector<std::string> out;
  for (const UnitInfo& u : kUnits)
    if (u.quantity == q) out.push_back(u.name);
  return out;
}

std::string Join(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : ", ") + s;
  return out;
}

const char* SiName(Quantity q) {
  switch (q) {
    case Quantity::kTime:
      return "s";
    case Quantity::kLength:
      return "m";
    case Quantity::kVelocity:
      return "m/s";
    case Quantity::kAcceleration:
      return "m/s^2";
    case Quantity::kForce:
      return "N";
    case Quantity::kVoltage:
      return "V";
    case Quantity::kNone:
      break;
  }
  return "";
}

struct ColumnRef {
  int index = -1;
  double factor = 1;  // unit to SI
};

// The column `role` reads: the header cell whose text is `wanted`, else the one whose name (unit
// suffix stripped) is; the nearest name suggested when none is, an error when two are. Its unit,
// for a column of quantity `q`: a unit of q converts to SI (and then `scale` must be 1: one
// conversion only); a unit of another quantity is an error; any other unit (a sensor's volts) is read
// as is only when the scale flag says how (scale != 1) — else a misspelt unit would be taken as SI; the
// time column must be in a time unit.
StatusOr<ColumnRef> FindColumn(const std::vector<HeaderCell>& header, const std::string& wanted,
                               const std::string& role, Quantity q, double scale, const char* scale_field,
                               const std::string& file) {
  std::vector<int> hits;
  for (size_t i = 0; i < header.size(); ++i)
    if (header[i].text == wanted) hits.push_back(static_cast<int>(i));
  if (hits.empty())
    for (size_t i = 0; i < header.size(); ++i)
      if (header[i].name == wanted) hits.push_back(static_cast<int>(i));
  if (hits.empty()) {
    std::vector<std::string> names;
    for (const HeaderCell& h : header) names.push_back(h.name);
    return Status::InvalidArgument(role, file + " (" + role + "): " + UnknownNameMessage("column", wanted, names));
  }
  if (hits.size() > 1)
    return Status::InvalidArgument(role, file + " (" + role + "): columns '" + Printable(header[hits[0]].text) +
                                             "' and '" + Printable(header[hits[1]].text) + "' both match '" +
                                             Printable(wanted) + "'; name one as the header spells it");
  const HeaderCell& h = header[hits[0]];
  ColumnRef ref{hits[0], 1.0};
  if (h.unit.empty() || q == Quantity::kNone) return ref;
  const std::string where = file + " column '" + Printable(h.text) + "' (" + role +
                            (role == QuantityName(q) ? std::string() : std::string(", ") + QuantityName(q)) + ")";
  const UnitInfo* u = FindUnit(h.unit);
  // Volts on a column of another quantity are a sensor's raw reading (`laser [V]`): an unknown unit
  // there, read as is with a scale, not a unit of the wrong quantity.
  if (u && u->quantity == Quantity::kVoltage && q != Quantity::kVoltage) u = nullptr;
  if (u && u->quantity == q) {
    if (scale != 1.0)
      return Status::InvalidArgument(scale_field, where + ": the header gives the unit " + Printable(h.unit) +
                                                      ", converted to " + SiName(q) + "; " + scale_field + " = " +
                                                      FormatNumber(scale) +
                                                      " would convert it again (use one or the other)");
    ref.factor = u->to_si;
    return ref;
  }
  if (u)
    return Status::InvalidArgument(role, where + ": '" + Printable(h.unit) + "' is a unit of " +
                                             QuantityName(u->quantity) + "; a " + QuantityName(q) + " column takes " +
                                             Join(UnitNames(q)));
  if (q == Quantity::kTime)
    return Status::InvalidArgument(role, where + ": " + UnknownNameMessage("time unit", h.unit, UnitNames(q)));
  if (scale == 1.0) {
    const bool has_flag = scale_field[0] != '\0';
    return Status::InvalidArgument(
        has_flag ? std::string(scale_field) : role,
        where + ": '" + Printable(h.unit) + "' is no unit of " + QuantityName(q) + " (" + Join(UnitNames(q)) + ")" +
            (has_flag
                 ? std::string("; to read the column as is, give ") + scale_field + " (the factor to " + SiName(q) + ")"
                 : std::string()));
  }
  return ref;
}

Quantity InputQuantity(InputKind k) {
  switch (k) {
    case InputKind::kBaseDisplacement:
      return Quantity::kLength;
    case InputKind::kBaseAcceleration:
      return Quantity::kAcceleration;
    case InputKind::kForce:
      return Quantity::kForce;
  }
  return Quantity::kNone;
}

Quantity OutputQuantity(OutputKind k) {
  switch (k) {
    case OutputKind::kDisplacement:
      return Quantity::kLength;
    case OutputKind::kVelocity:
      return Quantity::kVelocity;
    case OutputKind::kAnalogue:
      return Quantity::kNone;
  }
  return Quantity::kNone;
}

// The data lines of a CSV file: the next line that is neither blank nor a comment ('#' first), without a UTF-8 BOM
// or a CR; At() names the file and the row for messages.
class DataLines {
 public:
  DataLines(std::unique_ptr<LineReader> reader, std::string file)
      : reader_(std::move(reader)), file_(std::move(file)) {}
  std::string At() const { return file_ + " row " + std::to_string(reader_->line_number()); }
  const std::string& line() const { return line_; }
  // True with the next line in line(), false at the end.
  StatusOr<bool> Next() {
    for (;;) {
      auto r = reader_->Next(&line_);
      if (!r.ok()) return r.status();
      if (*r == LineReader::Result::kEnd) return false;
      if (*r == LineReader::Result::kTooLong)
        return Status::InvalidArgument(
            "data", At() + ": the line is longer than " + std::to_string(limits::kMaxDataLineBytes) +
                        " bytes (violates line length <= " + std::to_string(limits::kMaxDataLineBytes) + ")");
      if (reader_->line_number() == 1) {
        if (line_.rfind("\xef\xbb\xbf", 0) == 0) line_.erase(0, 3);
        if (line_.rfind("\xff\xfe", 0) == 0 || line_.rfind("\xfe\xff", 0) == 0)
          return Status::InvalidArgument("data", file_ + " is UTF-16 text; save it as UTF-8 (or ASCII)");
      }
      if (!line_.empty() && line_.back() == '\r') line_.pop_back();
      const size_t first = line_.find_first_not_of(" \t");
      if (first == std::string::npos || line_[first] == '#') continue;
      return true;
    }
  }

 private:
  std::unique_ptr<LineReader> reader_;
  std::string file_;
  std::string line_;
};

// A file's header line: its separator, whether numbers take a decimal comma, whether lines end with a separator,
// and its cells.
struct Header {
  char sep = 0;
  bool decimal_comma = false, trailing_sep = false;
  std::vector<HeaderCell> cells;
};

// The header line `line` (lines: where it was read, for messages): the separator is the one of , tab ; that splits it
// most often.
StatusOr<Header> ReadHeader(const std::string& line, const DataLines& lines) {
  Header h;
  int best = 0;
  bool tie = false;
  for (char s : {',', '\t', ';'}) {
    const int n = CountOutsideQuotes(line, s);
    if (n > best)
      best = n, h.sep = s, tie = false;
    else if (n == best && n > 0)
      tie = true;
  }
  if (h.sep == 0)
    return Status::InvalidArgument(
        "data",
        lines.At() +
            " (header): no separator splits it (',' tab ';' were tried; the header names the columns, e.g. t,x0,x)");
  if (tie)
    return Status::InvalidArgument("data", lines.At() + " (header): it splits as often at " + SeparatorName(h.sep) +
                                               " as at another of ',' tab ';'; quote the names that hold a separator");
  h.decimal_comma = h.sep != ',';
  std::vector<std::string> cells;
  std::string split_error;
  if (!SplitLine(line, h.sep, &cells, &split_error))
    return Status::InvalidArgument("data", lines.At() + " (header) " + split_error);
  // A trailing separator (some exports end every line with one) makes no column.
  h.trailing_sep = cells.size() > 1 && cells.back().empty();
  if (h.trailing_sep) cells.pop_back();
  bool all_numbers = true;
  for (const std::string& cell : cells) {
    h.cells.push_back(ParseHeaderCell(cell));
    double v;
    all_numbers = all_numbers && ParseNumber(cell, h.decimal_comma, &v);
  }
  if (all_numbers)
    return Status::InvalidArgument("data", lines.At() +
                                               ": the first line that is not a comment holds numbers, not column names "
                                               "(a header line is required; comment lines start with #)");
  return h;
}

// The columns a ColumnMap names in a header (FindColumn): time, input, output, and the optional resonator,
// voltage and group columns (index -1 where not named).
struct Columns {
  ColumnRef t, in, out, res, volt;
  std::vector<int> group;
};

StatusOr<Columns> FindColumns(const std::vector<HeaderCell>& header, const ColumnMap& c, const std::string& file) {
  Columns cols;
  auto ct = FindColumn(header, c.time, "time", Quantity::kTime, 1.0, "", file);
  if (!ct.ok()) return ct.status();
  auto ci = FindColumn(header, c.input, "input", InputQuantity(c.input_kind), c.input_scale, "input_scale", file);
  if (!ci.ok()) return ci.status();
  auto co = FindColumn(header, c.output, "output", OutputQuantity(c.output_kind), c.output_scale, "output_scale", file);
  if (!co.ok()) return co.status();
  cols.t = *ct, cols.in = *ci, cols.out = *co;
  if (!c.resonator.empty()) {
    auto r = FindColumn(header, c.resonator, "resonator", Quantity::kLength, 1.0, "", file);
    if (!r.ok()) return r.status();
    cols.res = *r;
  }
  if (!c.voltage.empty()) {
    auto r = FindColumn(header, c.voltage, "output2", Quantity::kVoltage, c.voltage_scale, "output2_scale", file);
    if (!r.ok()) return r.status();
    cols.volt = *r;
  }
  for (const auto& g : c.group) {
    auto r = FindColumn(header, g, "group", Quantity::kNone, 1.0, "", file);
    if (!r.ok()) return r.status();
    cols.group.push_back(r->index);
  }
  return cols;
}

// The numbers of one data line's cells into *row (each finite and within limits::kMaxDataMagnitude).
Status ParseRow(const std::vector<std::string>& cells, const Header& h, const DataLines& lines,
                std::vector<double>* row) {
  for (size_t k = 0; k < cells.size(); ++k) {
    double v = 0;
    if (!ParseNumber(cells[k], h.decimal_comma, &v))
      return Status::InvalidArgument("data", lines.At() + " column '" + Printable(h.cells[k].text) + "': '" +
                                                 Printable(cells[k]) + "' is not a finite number");
    if (!(std::fabs(v) <= limits::kMaxDataMagnitude))
      return Status::InvalidArgument("data", lines.At() + " column '" + Printable(h.cells[k].text) +
                                                 "': " + Printable(cells[k]) +
                                                 " violates |value| <= " + FormatNumber(limits::kMaxDataMagnitude));
    (*row)[k] = v;
  }
  return Status::Ok();
}

// Starts a new record at time t with group values gv where one begins (the first row, the group columns change, or
// time restarts at the first record's start); an error where time goes back otherwise, a record would hold a single
// row, or the file more than limits::kMaxDataRecords records. `name`: the file's, for the records' names.
Status StartRecordIfNew(double t, const std::vector<double>& gv, const std::string& name, const DataLines& lines,
                        std::vector<Record>* records) {
  const bool back = !records->empty() && t <= records->back().t.back();
  // Time may go back only to restart a record at the first record's start time (concatenated
  // records, e.g. the harvester's steady-sine file); anything else is a broken time column.
  if (back && gv == records->back().group_values) {
    const double start = records->front().t.front();
    const double dt = records->back().t.size() >= 2 ? records->back().t[1] - records->back().t[0] : 0.0;
    if (!(std::abs(t - start) <= 0.5 * std::abs(dt)) || records->back().t.size() < 2)
      return Status::InvalidArgument("data", lines.At() + ": time " + FormatNumber(t) +
                                                 (t == records->back().t.back() ? " repeats" : " is before") +
                                                 " the previous row's " + FormatNumber(records->back().t.back()) +
                                                 " (time must increase; a restart must return to " +
                                                 FormatNumber(start) + ")");
  }
  const bool restart = records->empty() || back || gv != records->back().group_values;
  if (!restart) return Status::Ok();
  if (!records->empty() && records->back().t.size() < 2)
    return Status::InvalidArgument("data", lines.At() + ": a record of a single row");
  if (static_cast<long>(records->size()) >= limits::kMaxDataRecords)
    return Status::InvalidArgument(
        "data", lines.At() + ": more than " + std::to_string(limits::kMaxDataRecords) +
                    " records in one file (violates records <= " + std::to_string(limits::kMaxDataRecords) +
                    "; a record starts where the group columns change or time restarts)");
  Record r;
  r.name = name + "#" + std::to_string(records->size());
  r.group_values = gv;
  records->push_back(std::move(r));
  return Status::Ok();
}

// Every record's mean step (dt), and an error where a record has fewer than two samples or its sampling is not
// uniform.
Status SetSteps(std::vector<Record>* records) {
  for (Record& r : *records) {
    if (r.t.size() < 2) return Status::InvalidArgument("data", Printable(r.name, 200) + ": fewer than two samples");
    r.dt = (r.t.back() - r.t.front()) / static_cast<double>(r.t.size() - 1);
    // 25 % of a step: printed time columns are quantised (the harvester's 64 Hz file prints 10.016 for
    // 10.015625, a 6 % step error), while a dropped or duplicated sample moves a step by 100 %. The
    // mean step is used from here on.
    for (size_t i = 1; i < r.t.size(); ++i)
      if (std::fabs(r.t[i] - r.t[i - 1] - r.dt) > 0.25 * r.dt)
        return Status::InvalidArgument(
            "data", Printable(r.name, 200) + ": sampling is not uniform near t = " + FormatNumber(r.t[i]) +
                        " s (step " + FormatNumber(r.t[i] - r.t[i - 1]) + " s, mean " + FormatNumber(r.dt) + " s)");
  }
  return Status::Ok();
}

}  // namespace

StatusOr<std::vector<Record>> LoadRecords(const std::string& path, const ColumnMap& c) {
  if (!(std::isfinite(c.input_scale) && c.input_scale != 0))
    return Violates("input_scale", c.input_scale, "finite and != 0");
  if (!(std::isfinite(c.output_scale) && c.output_scale != 0))
    return Violates("output_scale", c.output_scale, "finite and != 0");
  if (!(std::isfinite(c.voltage_scale) && c.voltage_scale != 0))
    return Violates("output2_scale", c.voltage_scale, "finite and != 0");
  auto reader = LineReader::Open(path, "data", limits::kMaxDataLineBytes);
  if (!reader.ok()) return reader.status();
  const std::string name = std::filesystem::path(path).filename().string();  // records' names
  const std::string file = Printable(name, 200);                             // in messages
  DataLines lines(std::move(reader).value(), file);

  auto has = lines.Next();
  if (!has.ok()) return has.status();
  if (!*has) return Status::InvalidArgument("data", file + " is empty (a header line is required)");
  auto header = ReadHeader(lines.line(), lines);
  if (!header.ok()) return header.status();
  auto cols = FindColumns(header->cells, c, file);
  if (!cols.ok()) return cols.status();
  const ColumnRef &ct = cols->t, &ci = cols->in, &co = cols->out, &cr = cols->res, &cv = cols->volt;
  const double time_factor = ct.factor, in_factor = ci.factor * c.input_scale, out_factor = co.factor * c.output_scale;

  std::vector<Record> records;
  std::vector<std::string> cells;
  std::string split_error;
  std::vector<double> row(header->cells.size());
  long rows = 0;
  for (;;) {
    has = lines.Next();
    if (!has.ok()) return has.status();
    if (!*has) break;
    if (++rows > limits::kMaxDataRows)
      return Status::InvalidArgument(
          "data", lines.At() + ": more than " + std::to_string(limits::kMaxDataRows) +
                      " data rows (violates rows <= " + std::to_string(limits::kMaxDataRows) + "; split the file)");
    if (!SplitLine(lines.line(), header->sep, &cells, &split_error))
      return Status::InvalidArgument("data", lines.At() + " " + split_error);
    if (header->trailing_sep && cells.size() == header->cells.size() + 1 && cells.back().empty()) cells.pop_back();
    if (cells.size() != header->cells.size())
      return Status::InvalidArgument("data", lines.At() + ": " + std::to_string(cells.size()) +
                                                 " cells, the header has " + std::to_string(header->cells.size()));
    BISTABLE_RETURN_IF_ERROR(ParseRow(cells, *header, lines, &row));
    std::vector<double> gv;
    for (int g : cols->group) gv.push_back(row[g]);
    const double t = row[ct.index] * time_factor;
    BISTABLE_RETURN_IF_ERROR(StartRecordIfNew(t, gv, name, lines, &records));
    const double scaled_in = row[ci.index] * in_factor, scaled_out = row[co.index] * out_factor;
    const double scaled_res = cr.index >= 0 ? row[cr.index] * cr.factor : 0.0;
    const double volt_factor = cv.factor * c.voltage_scale;
    const double scaled_volt = cv.index >= 0 ? row[cv.index] * volt_factor : 0.0;
    for (auto [v, k, factor] :
         {std::tuple{scaled_in, ci.index, in_factor}, std::tuple{scaled_out, co.index, out_factor},
          std::tuple{scaled_res, cr.index, cr.factor}, std::tuple{scaled_volt, cv.index, volt_factor}})
      if (k >= 0 && !(std::fabs(v) <= limits::kMaxDataMagnitude))
        return Status::InvalidArgument("data", lines.At() + " column '" + Printable(header->cells[k].text) +
                                                   "': " + Printable(cells[k]) + " x scale " + FormatNumber(factor) +
                                                   " violates |value| <= " + FormatNumber(limits::kMaxDataMagnitude));
    Record& r = records.back();
    r.t.push_back(t);
    r.input.push_back(scaled_in);
    r.output.push_back(scaled_out);
    if (cr.index >= 0) r.resonator.push_back(scaled_res);
    if (cv.index >= 0) r.voltage.push_back(scaled_volt);
  }
  if (records.empty()) return Status::InvalidArgument("data", file + " has a header but no rows");
  BISTABLE_RETURN_IF_ERROR(SetSteps(&records));
  if (records.size() == 1) records[0].name = name;
  return records;
}

}  // namespace bistable
