#include "identify/record.h"

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <tuple>

#include "base/names.h"
#include "base/limits.h"
#include "base/validate.h"

namespace bistable {
namespace {

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::stringstream ss(line);
  while (std::getline(ss, cell, ',')) {
    while (!cell.empty() && (cell.back() == '\r' || cell.back() == ' ')) cell.pop_back();
    size_t a = 0;
    while (a < cell.size() && cell[a] == ' ') ++a;
    out.push_back(cell.substr(a));
  }
  return out;
}

StatusOr<int> Column(const std::vector<std::string>& header, const std::string& name, const std::string& role,
                     const std::string& file) {
  for (size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return static_cast<int>(i);
  return Status::InvalidArgument(role, file + " (" + role + "): " + UnknownNameMessage("column", name, header));
}

}  // namespace

StatusOr<std::vector<Record>> LoadRecords(const std::string& path, const ColumnMap& c) {
  std::ifstream in(path);
  if (!in) return Status::InvalidArgument("data", "cannot read data file '" + path + "'");
  const std::string file = std::filesystem::path(path).filename().string();
  if (!(std::isfinite(c.input_scale) && c.input_scale != 0)) return Violates("input_scale", c.input_scale, "finite and != 0");
  if (!(std::isfinite(c.output_scale) && c.output_scale != 0)) return Violates("output_scale", c.output_scale, "finite and != 0");
  std::string line;
  if (!std::getline(in, line)) return Status::InvalidArgument("data", file + " is empty (a header line is required)");
  const std::vector<std::string> header = SplitCsv(line);
  auto ct = Column(header, c.time, "time", file);
  auto ci = Column(header, c.input, "input", file);
  auto co = Column(header, c.output, "output", file);
  if (!ct.ok()) return ct.status();
  if (!ci.ok()) return ci.status();
  if (!co.ok()) return co.status();
  int cr = -1;
  if (!c.resonator.empty()) {
    auto r = Column(header, c.resonator, "resonator", file);
    if (!r.ok()) return r.status();
    cr = *r;
  }
  std::vector<int> cg;
  for (const auto& g : c.group) {
    auto r = Column(header, g, "group", file);
    if (!r.ok()) return r.status();
    cg.push_back(*r);
  }

  std::vector<Record> records;
  std::vector<double> row(header.size());
  long row_no = 1;
  while (std::getline(in, line)) {
    ++row_no;
    if (line.empty() || line == "\r") continue;
    const std::vector<std::string> cells = SplitCsv(line);
    if (cells.size() != header.size())
      return Status::InvalidArgument("data", file + " row " + std::to_string(row_no) + ": " + std::to_string(cells.size()) +
                                                 " cells, the header has " + std::to_string(header.size()));
    for (size_t k = 0; k < cells.size(); ++k) {
      double v = 0;
      const auto [p, ec] = std::from_chars(cells[k].data(), cells[k].data() + cells[k].size(), v);
      if (ec != std::errc() || p != cells[k].data() + cells[k].size() || !std::isfinite(v))
        return Status::InvalidArgument("data", file + " row " + std::to_string(row_no) + " column '" + header[k] +
                                                   "': '" + cells[k] + "' is not a finite number");
      if (!(std::fabs(v) <= limits::kMaxDataMagnitude))
        return Status::InvalidArgument("data", file + " row " + std::to_string(row_no) + " column '" + header[k] + "': " +
                                                   cells[k] + " violates |value| <= " + FormatNumber(limits::kMaxDataMagnitude));
      row[k] = v;
    }
    std::vector<double> gv;
    for (int g : cg) gv.push_back(row[g]);
    const double t = row[*ct];
    const bool back = !records.empty() && t <= records.back().t.back();
    // Time may go back only to restart a record at the first record's start time (concatenated
    // records, e.g. the harvester's steady-sine file); anything else is a broken time column.
    if (back && gv == records.back().group_values) {
      const double start = records.front().t.front();
      const double dt = records.back().t.size() >= 2 ? records.back().t[1] - records.back().t[0] : 0.0;
      if (!(std::abs(t - start) <= 0.5 * std::abs(dt)) || records.back().t.size() < 2)
        return Status::InvalidArgument("data", file + " row " + std::to_string(row_no) + ": time " + FormatNumber(t) +
                                                   (t == records.back().t.back() ? " repeats" : " is before") +
                                                   " the previous row's " + FormatNumber(records.back().t.back()) +
                                                   " (time must increase; a restart must return to " + FormatNumber(start) + ")");
    }
    const bool restart = records.empty() || back || gv != records.back().group_values;
    if (restart) {
      if (!records.empty() && records.back().t.size() < 2)
        return Status::InvalidArgument("data", file + " row " + std::to_string(row_no) + ": a record of a single row");
      Record r;
      r.name = file + "#" + std::to_string(records.size());
      r.group_values = gv;
      records.push_back(std::move(r));
    }
    const double scaled_in = row[*ci] * c.input_scale, scaled_out = row[*co] * c.output_scale;
    for (auto [v, k, scale] : {std::tuple{scaled_in, *ci, c.input_scale}, std::tuple{scaled_out, *co, c.output_scale}})
      if (!(std::fabs(v) <= limits::kMaxDataMagnitude))
        return Status::InvalidArgument("data", file + " row " + std::to_string(row_no) + " column '" + header[k] + "': " +
                                                   cells[k] + " x scale " + FormatNumber(scale) + " violates |value| <= " +
                                                   FormatNumber(limits::kMaxDataMagnitude));
    Record& r = records.back();
    r.t.push_back(t);
    r.input.push_back(row[*ci] * c.input_scale);
    r.output.push_back(row[*co] * c.output_scale);
    if (cr >= 0) r.resonator.push_back(row[cr]);
  }
  if (records.empty()) return Status::InvalidArgument("data", file + " has a header but no rows");
  for (Record& r : records) {
    if (r.t.size() < 2) return Status::InvalidArgument("data", r.name + ": fewer than two samples");
    r.dt = (r.t.back() - r.t.front()) / static_cast<double>(r.t.size() - 1);
    // 25 % of a step: printed time columns are quantised (the harvester's 64 Hz file prints 10.016 for
    // 10.015625, a 6 % step error), while a dropped or duplicated sample moves a step by 100 %. The
    // mean step is used from here on.
    for (size_t i = 1; i < r.t.size(); ++i)
      if (std::fabs(r.t[i] - r.t[i - 1] - r.dt) > 0.25 * r.dt)
        return Status::InvalidArgument("data", r.name + ": sampling is not uniform near t = " + FormatNumber(r.t[i]) +
                                                   " s (step " + FormatNumber(r.t[i] - r.t[i - 1]) + " s, mean " +
                                                   FormatNumber(r.dt) + " s)");
  }
  if (records.size() == 1) records[0].name = file;
  return records;
}

}  // namespace bistable
