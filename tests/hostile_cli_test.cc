// Hostile input against the client (issue 10, client side): every place user text or a path reaches
// gnuplot, the file system or a parser, tried with strings an attacker would send. Each row of the
// table is its own test case: the `bistable` CLI runs as a real process (fork + execve, an argument
// vector: no shell between the test and the CLI), in a fresh directory that is also its working
// directory. Every row checks that no command ran (no file named "pwned" appears), that no process
// died of a signal, that no temporary plot file is left behind, and then its own outcome: a clear
// error (exit 2, the field named in stderr) or success with the files written (and, for SVG plots,
// the title shown as the literal text).
//
// Plain unit tests of GnuplotString (client/plot.h) follow the table, including a round trip of every
// byte through the installed gnuplot.
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <nlohmann/json.hpp>

#include "client/plot.h"
#include "storage/map_file.h"
#include "tests/process_util.h"

namespace {

namespace fs = std::filesystem;
using bistable_test::ExecResult;
using bistable_test::RunArgv;

// ---- helpers ----------------------------------------------------------------------------------

std::string ReplaceAll(std::string s, const std::string& from, const std::string& to) {
  for (size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size())) s.replace(p, from.size(), to);
  return s;
}

// A TOML basic string holding `s` exactly.
std::string TomlString(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20 || c == 0x7f) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", c);
      out += b;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out + "\"";
}

// Text as gnuplot's SVG terminal writes it (it escapes & and <, not >).
std::string XmlEscape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '&')
      out += "&amp;";
    else if (c == '<')
      out += "&lt;";
    else
      out += c;
  }
  return out;
}

// A 2 x 2 standalone sweep with a short run (well under a second, plots included).
std::string TinySpec(const std::string& name) {
  return "name = " + TomlString(name) +
         "\nmodel = \"standalone\"\n[axes]\nalpha = [0.5, 1.0]\nomega = [0.8, 1.2]\n"
         "[integration]\nt_end = 20.0\nt_keep = 10.0\n";
}

// A measured-record CSV (t, x0, x) of n samples at 100 Hz; `cell(i, col)` may override a cell.
std::string RecordCsv(int n, const std::map<std::pair<int, int>, std::string>& cells = {}, double scale = 1.0) {
  std::ostringstream os;
  os.precision(9);
  os << "t,x0,x\n";
  for (int i = 0; i < n; ++i) {
    std::string c[3];
    std::ostringstream a, b, t;
    a.precision(9), b.precision(9), t.precision(9);
    t << i * 0.01;
    a << scale * 0.001 * std::sin(i * 0.3);
    b << scale * 0.0012 * std::sin(i * 0.3 - 0.2);
    c[0] = t.str(), c[1] = a.str(), c[2] = b.str();
    for (int k = 0; k < 3; ++k)
      if (auto it = cells.find({i, k}); it != cells.end()) c[k] = it->second;
    os << c[0] << "," << c[1] << "," << c[2] << "\n";
  }
  return os.str();
}

// ---- the table ----------------------------------------------------------------------------------

enum class Outcome {
  kOk,     // every step exits 0
  kError,  // a step exits 2 with err_has in its stderr (later steps are not run)
};

enum class JsonCheck {
  kNone,
  kRunFiles,        // step 0 is `run --json`: every file it lists exists and is not empty
  kIdentifyFinite,  // the last step is `identify --json`: parameters are numbers, simulations >= 0
};

// Placeholders in arguments, paths and environment values: {dir} the row's directory (also the
// working directory), {canary} = {dir}/pwned, {spec} = {dir}/spec.toml, {data} = {dir}/data,
// {id} = the sweep id printed by step 0 (`run --json`), {name} = the spec name (in svg_has).
struct Row {
  std::string name;
  std::string spec_name;                        // non-empty: {spec} is TinySpec(this)
  std::vector<std::vector<std::string>> steps;  // bistable arguments, one process each
  Outcome outcome = Outcome::kOk;
  std::string err_has;                                     // error outcomes: in the failing step's stderr
  std::string err_lacks;                                   // never in any step's stderr or stdout (a secret)
  size_t err_max_bytes = 0;                                // > 0: the failing step's stderr is at most this long
  std::vector<std::string> out_has;                        // outcome ok: in the last step's stdout
  std::vector<std::string> ok_files;                       // outcome ok: exist, not empty
  std::vector<std::string> absent;                         // never exist afterwards
  std::string svg;                                         // outcome ok: an SVG whose text is checked
  std::vector<std::string> svg_has;                        // literal (XML-escaped) substrings of it
  std::map<std::string, std::string> env;                  // environment of every step
  std::string fake_gnuplot;                                // non-empty: {dir}/fakebin/gnuplot with this body
  std::vector<std::pair<std::string, std::string>> files;  // written before the steps
  JsonCheck json = JsonCheck::kNone;

  // Builders for the table below.
  Row& Error(const std::string& has) { return outcome = Outcome::kError, err_has = has, *this; }
  Row& OkFiles(std::vector<std::string> f) { return ok_files = std::move(f), *this; }
  Row& Absent(std::vector<std::string> f) { return absent = std::move(f), *this; }
  Row& Files(std::vector<std::pair<std::string, std::string>> f) { return files = std::move(f), *this; }
  Row& Json(JsonCheck j) { return json = j, *this; }
};

Row Case(const std::string& name, std::vector<std::vector<std::string>> steps) {
  Row r;
  r.name = name;
  r.steps = std::move(steps);
  return r;
}

std::ostream& operator<<(std::ostream& os, const Row& r) { return os << r.name; }

std::vector<std::string> Run(bool plots) {
  std::vector<std::string> v = {"run", "{spec}", "--data", "{data}", "--json", "--quiet"};
  if (!plots) v.push_back("--no-plots");
  return v;
}
std::vector<std::string> Map(std::vector<std::string> extra) {
  std::vector<std::string> v = {"map", "{id}", "--data", "{data}"};
  v.insert(v.end(), extra.begin(), extra.end());
  return v;
}
std::vector<std::string> Query(const std::string& expr) { return {"query", "{id}", expr, "--data", "{data}"}; }
std::vector<std::string> Identify(const std::string& data, std::vector<std::string> extra = {}) {
  std::vector<std::string> v = {"identify",
                                "--data",
                                data,
                                "--terms",
                                "main.linear,main.viscous",
                                "--known",
                                "m_main=1",
                                "--max-added",
                                "0",
                                "--global-evals",
                                "0",
                                "--horizon",
                                "0"};
  v.insert(v.end(), extra.begin(), extra.end());
  return v;
}

// A sweep whose name is hostile: run with its default plots, then the map of lle as SVG, whose
// title must be the literal name; the axis labels keep their enhanced-text symbols.
Row NameRow(const std::string& row_name, const std::string& spec_name, Outcome outcome = Outcome::kOk,
            const std::string& err_has = "") {
  Row r;
  r.name = row_name;
  r.spec_name = spec_name;
  r.steps = {Run(true), Map({"--metric", "lle", "--format", "svg", "--out", "{dir}/title.svg"})};
  r.outcome = outcome;
  r.err_has = err_has;
  r.json = JsonCheck::kRunFiles;
  r.ok_files = {"{dir}/title.svg"};
  if (outcome == Outcome::kOk) {
    r.svg = "{dir}/title.svg";
    // The name in the footer, literally; the title is the metric's, the axes typeset (docs/figures.md).
    r.svg_has = {"{name}  \u00b7  sweep ", "Largest Lyapunov exponent", "\u03b1"};
  }
  return r;
}

// A plain sweep, then one command against it.
Row OnSweep(const std::string& row_name, std::vector<std::string> step, Outcome outcome,
            const std::string& err_has = "", std::vector<std::string> ok_files = {},
            std::vector<std::string> absent = {}) {
  Row r;
  r.name = row_name;
  r.spec_name = "plain";
  r.steps = {Run(false), std::move(step)};
  r.outcome = outcome;
  r.err_has = err_has;
  r.ok_files = std::move(ok_files);
  r.absent = std::move(absent);
  return r;
}

std::string Repeat(const std::string& s, int n) {
  std::string out;
  for (int i = 0; i < n; ++i) out += s;
  return out;
}

// -- Record marks on map figures (`map --mark X,Y,LABEL`, `--marks FILE.csv`): labels reach gnuplot as text,
// never as code (shown literally in the SVG), and every bound is refused naming its flag. The tiny sweep's
// figure: omega (horizontal, X) drawn from 0.6 to 1.4, alpha (vertical, Y) from 0.25 to 1.25.
void AddMarkRows(std::vector<Row>* rows) {
  const auto marked = [](std::vector<std::string> extra, const std::string& format = "svg") {
    std::vector<std::string> v = {"--metric", "motion", "--format", format, "--out", "{dir}/marked." + format};
    v.insert(v.end(), extra.begin(), extra.end());
    return Map(v);
  };
  // Near the left edge, so each label fits on one line (one SVG text) to the right of its point.
  const std::vector<std::string> labels = {"q\"; system(\"touch pwned\"); print \"",
                                           "bq `touch pwned` $(touch pwned)",
                                           "mac @GPVAL_TERM @m; set output '|touch pwned'",
                                           "{/Symbol a} x^2 y_1 &{w} ~a <b>&amp;</b>",
                                           "sq ' \\ \\\" \\\\ end \\",
                                           "oct \\0601 \\140touch pwned\\140 \\\\0140",
                                           "\xce\xb1\xce\xb2 caf\xc3\xa9 \xe2\x9c\x93 \xe6\x97\xa5"};
  for (size_t i = 0; i < labels.size(); ++i) {
    Row r = OnSweep("mark_label_literal_" + std::to_string(i), marked({"--mark", "0.65,0.75," + labels[i]}),
                    Outcome::kOk, "", {"{dir}/marked.svg"});
    r.svg = "{dir}/marked.svg";
    r.svg_has = {labels[i]};  // XML-escaped by the check, as gnuplot writes it
    rows->push_back(r);
  }
  for (const std::string format : {"png", "pdf"})
    rows->push_back(OnSweep("mark_label_hostile_" + format, marked({"--mark", "0.65,0.75," + labels[0]}, format),
                            Outcome::kOk, "", {"{dir}/marked." + format}));
  const struct {
    std::string name, mark, says;
  } refused[] = {
      {"newline_command", "0.65,0.75,a\nset output '|touch pwned'", "character 2 of the label is U+000A"},
      {"carriage_return", "0.65,0.75,a\rb", "U+000D"},
      {"escape_sequence", "0.65,0.75,\x1b[2Jx", "U+001B"},
      {"bidi_override", "0.65,0.75,a \xe2\x80\xae b", "U+202E"},
      {"not_utf8", "0.65,0.75,a \xff b", "character 3 of the label is not UTF-8"},
      {"81_characters", "0.65,0.75," + std::string(81, 'x'), "longer than 80 characters (violates label <= 80"},
      {"x_nan", "nan,0.75,A", "X = 'nan' violates X a finite number"},
      {"y_huge", "0.65,1e999,A", "Y = '1e999' violates Y a finite number"},
      {"two_fields", "0.65,0.75", "violates X,Y,LABEL"},
      {"x_off_range", "2,0.75,far",
       "X = 2 is outside the figure's horizontal axis omega, drawn from 0.6 to 1.4 (its grid values 0.8 to 1.2 "
       "and half a grid step beyond); X is on the horizontal axis (omega), Y on the vertical (alpha)"},
      {"y_off_range", "0.65,1.3,far", "Y = 1.3 is outside the figure's vertical axis alpha, drawn from 0.25 to 1.25"},
      {"swapped_axes", "0.5,1.2,alpha first", "X = 0.5 is outside the figure's horizontal axis omega"},
  };
  for (const auto& r : refused)
    rows->push_back(OnSweep("mark_refused_" + r.name, marked({"--mark", r.mark}), Outcome::kError, "(mark: --mark '",
                            {}, {"{dir}/marked.svg"}));
  for (const auto& r : refused)  // and the message says why
    rows->push_back(OnSweep("mark_says_" + r.name, marked({"--mark", r.mark}), Outcome::kError, r.says));
  rows->push_back(OnSweep("mark_on_the_drawn_corners", marked({"--mark", "0.6,0.25,a", "--mark", "1.4,1.25,b"}),
                          Outcome::kOk, "", {"{dir}/marked.svg"}));
  rows->push_back(OnSweep("mark_80_characters", marked({"--mark", "0.65,0.75," + std::string(80, 'x')}), Outcome::kOk,
                          "", {"{dir}/marked.svg"}));
  rows->push_back(OnSweep("mark_on_csv", Map({"--metric", "motion", "--format", "csv", "--mark", "0.65,0.75,A"}),
                          Outcome::kError,
                          "(mark: --mark and --marks draw on a figure: give --format png, svg or pdf"));
  rows->push_back(OnSweep("mark_on_a_curve",
                          Map({"--metric", "motion", "--format", "svg", "--at", "alpha=0.5", "--out", "{dir}/c.svg",
                               "--mark", "0.9,0.5,A"}),
                          Outcome::kError, "(mark: --mark draws on a heatmap over two free axes; this figure has 1", {},
                          {"{dir}/c.svg"}));
  rows->push_back(OnSweep("mark_on_hd_scatter",
                          Map({"--metric", "hd_scatter", "--at", "alpha=0.5", "--mark", "0.9,0.5,A"}), Outcome::kError,
                          "not on the hd_scatter figure"));
  {
    std::vector<std::string> many;
    for (int i = 0; i < 201; ++i) many.insert(many.end(), {"--mark", "1,0.75,m" + std::to_string(i)});
    rows->push_back(OnSweep("mark_201_times", marked(many), Outcome::kError,
                            "(mark: more than 200 marks (at --mark '1,0.75,m200'"));
  }
  // --marks FILE.csv: a header, comments, blank lines, CRLF, CSV quoting; hostile labels literally.
  {
    Row r = OnSweep("marks_file_literal", marked({"--marks", "{dir}/m.csv"}), Outcome::kOk, "", {"{dir}/marked.svg"});
    r.files = {{"{dir}/m.csv",
                "# where we measured\r\nx,y,label\r\n\r\n0.65,0.5,A: intrawell\r\n  # skipped\n"
                "0.65,1.0,\"B, run #2 \"\"q\"\" `touch pwned`\"\n"}};
    r.svg = "{dir}/marked.svg";
    r.svg_has = {"A: intrawell", "B, run #2 \"q\" `touch pwned`"};
    rows->push_back(r);
  }
  {
    std::string text = "x,y,label\n";
    for (int i = 0; i < 200; ++i) text += "1,0.75,m" + std::to_string(i) + "\n";
    rows->push_back(
        OnSweep("marks_file_200_rows", marked({"--marks", "{dir}/many.csv"}), Outcome::kOk, "", {"{dir}/marked.svg"})
            .Files({{"{dir}/many.csv", text}}));
    rows->push_back(OnSweep("marks_file_201_rows", marked({"--marks", "{dir}/many.csv"}), Outcome::kError,
                            "(marks: more than 200 marks (at --marks '")
                        .Files({{"{dir}/many.csv", text + "1,0.75,m200\n"}}));
    rows->push_back(OnSweep("marks_file_200_rows_and_a_mark",
                            marked({"--mark", "1,0.75,one", "--marks", "{dir}/many.csv"}), Outcome::kError,
                            "violate marks <= 200")
                        .Files({{"{dir}/many.csv", text}}));
  }
  rows->push_back(OnSweep("marks_file_bad_row", marked({"--marks", "{dir}/bad.csv"}), Outcome::kError,
                          "bad.csv' line 3: character 2 of the label is U+001B")
                      .Files({{"{dir}/bad.csv", "x,y,label\n1,0.75,ok\n1,0.75,a\x1b]0;title\x07\n"}}));
  rows->push_back(OnSweep("marks_file_missing", marked({"--marks", "{dir}/none.csv"}), Outcome::kError,
                          "(marks: cannot read marks file '"));
  rows->push_back(
      OnSweep("marks_file_is_a_directory", marked({"--marks", "{dir}"}), Outcome::kError, "is not a regular file"));
}

std::vector<Row> Rows() {
  std::vector<Row> rows;
  // -- 1. The sweep's name in plot titles (gnuplot double-quoted strings), run plots and map plots.
  rows.push_back(NameRow("name_backquote", "bq `touch {canary}` end"));
  rows.push_back(NameRow("name_dollar_paren", "dp $(touch {canary}) end"));
  rows.push_back(NameRow("name_newline_system", "nl\nsystem(\"touch {canary}\")\nset output '|touch {canary}'",
                         Outcome::kError, "name"));
  rows.push_back(NameRow("name_macro", "mac @GPVAL_TERM @m end"));
  rows.push_back(NameRow("name_quote_breakout", "q\"; system(\"touch {canary}\"); print \""));
  rows.push_back(NameRow("name_single_quote_backslash", "sq ' \\ \\\" \\\\ end \\"));
  rows.push_back(NameRow("name_semicolon_hash", "a; system('touch {canary}') # b"));
  rows.push_back(NameRow("name_pipe", "|touch {canary}"));
  rows.push_back(NameRow("name_unicode", "\xce\xb1\xce\xb2\xce\xb3 \xe6\x97\xa5\xe6\x9c\xac \xe2\x9c\x93 caf\xc3\xa9"));
  rows.push_back(NameRow("name_enhanced_markup", "{/Symbol a} x^2 y_1 @z &{w} ~a"));
  rows.push_back(NameRow("name_xml_and_octal", "<b>&amp;</b> \\0601 \\140touch {canary}\\140"));

  // -- 2. Output paths: never in the script, never through a shell; a missing directory is an error.
  const auto png = [](const std::string& out) { return Map({"--metric", "frf_db", "--format", "png", "--out", out}); };
  rows.push_back(
      OnSweep("out_dollar_paren_relative", png("$(touch pwned).png"), Outcome::kOk, "", {"{dir}/$(touch pwned).png"}));
  rows.push_back(
      OnSweep("out_backquote_relative", png("`touch pwned`.png"), Outcome::kOk, "", {"{dir}/`touch pwned`.png"}));
  rows.push_back(OnSweep("out_pipe_relative", png("|touch pwned"), Outcome::kOk, "", {"{dir}/|touch pwned"}));
  rows.push_back(OnSweep("out_pipe_absolute", png("|touch {canary}"), Outcome::kError, "invalid argument (out: ", {},
                         {"{dir}/|touch "}));
  rows.push_back(OnSweep("out_newline_relative", png("n\nset output '|touch pwned'\n.png"), Outcome::kOk, "",
                         {"{dir}/n\nset output '|touch pwned'\n.png"}));
  rows.push_back(OnSweep("out_quote_relative", png("q\"; system(\"touch pwned\") #.png"), Outcome::kOk, "",
                         {"{dir}/q\"; system(\"touch pwned\") #.png"}));
  rows.push_back(
      OnSweep("out_dollar_absolute", png("{dir}/$(touch {canary}).png"), Outcome::kError, "invalid argument (out: "));
  rows.push_back(OnSweep("out_svg_hostile",
                         Map({"--metric", "motion", "--format", "svg", "--out", "s`touch pwned`.svg"}), Outcome::kOk,
                         "", {"{dir}/s`touch pwned`.svg"}));
  rows.push_back(
      OnSweep("out_missing_dir_png", png("{dir}/nodir/x.png"), Outcome::kError, "does not exist", {}, {"{dir}/nodir"}));
  rows.push_back(OnSweep("out_missing_dir_svg",
                         Map({"--metric", "lle", "--format", "svg", "--out", "{dir}/nodir/x.svg"}), Outcome::kError,
                         "invalid argument (out: ", {}, {"{dir}/nodir"}));
  rows.push_back(OnSweep("out_missing_dir_json",
                         Map({"--metric", "lle", "--format", "json", "--out", "{dir}/nodir/x.json"}), Outcome::kError,
                         "invalid argument (out: ", {}, {"{dir}/nodir"}));
  rows.push_back(OnSweep("out_missing_dir_csv",
                         Map({"--metric", "lle", "--format", "csv", "--out", "{dir}/nodir/x.csv"}), Outcome::kError,
                         "invalid argument (out: ", {}, {"{dir}/nodir"}));
  rows.push_back(OnSweep("out_json_hostile",
                         Map({"--metric", "lle", "--format", "json", "--out", "j`touch pwned`$(touch pwned).json"}),
                         Outcome::kOk, "", {"{dir}/j`touch pwned`$(touch pwned).json"}));
  rows.push_back(OnSweep("out_is_a_directory", png("{dir}/data"), Outcome::kError, "(out: "));
  rows.push_back(OnSweep("out_trailing_slash", png("{dir}/sub/"), Outcome::kError, "invalid argument (out: "));
  {
    Row r = OnSweep("out_parent_is_a_file", png("{dir}/file.txt/x.png"), Outcome::kError, "is not a directory");
    r.files = {{"{dir}/file.txt", "not a directory\n"}};
    rows.push_back(r);
  }
  rows.push_back(OnSweep("hd_scatter_missing_dir",
                         Map({"--metric", "hd_scatter", "--at", "alpha=0.5", "--out", "{dir}/nodir/h.png"}),
                         Outcome::kError, "invalid argument (out: ", {}, {"{dir}/nodir"}));
  rows.push_back(
      OnSweep("hd_scatter_hostile_out",
              Map({"--metric", "hd_scatter", "--at", "alpha=0.5", "--out", "h`touch pwned`$(touch pwned).png"}),
              Outcome::kOk, "", {"{dir}/h`touch pwned`$(touch pwned).png"}));
  {
    Row r;
    r.name = "run_data_dir_hostile";
    r.spec_name = "plain";
    r.steps = {{"run", "{spec}", "--data", "d`touch pwned`$(touch pwned)\"' |x", "--json", "--quiet"}};
    r.json = JsonCheck::kRunFiles;
    rows.push_back(r);
  }
  rows.push_back(Case("hbm_missing_dir", {{"hbm", "--out", "{dir}/nodir/b.png"}})
                     .Error("invalid argument (out: ")
                     .Absent({"{dir}/nodir"}));
  rows.push_back(Case("hbm_out_stdout", {{"hbm", "--out", "-"}})
                     .Error("invalid argument (out: --out - (standard output) is not supported: hbm's summary and "
                            "--json use standard output")
                     .Absent({"{dir}/-"}));
  rows.push_back(
      Case("hbm_fold_out_stdout", {{"hbm", "--fold-curve", "--fold-out", "-"}})
          .Error("invalid argument (fold_out: --fold-out - (standard output) is not supported: hbm's summary")
          .Absent({"{dir}/-"}));
  // fetch --out -: refused before any connection (no file named "-", nothing half-written to stdout).
  rows.push_back(
      Case("fetch_out_stdout", {{"fetch", "abc", "--out", "-", "--coordinator", "127.0.0.1:9"}})
          .Error(
              "invalid argument (out: --out - (standard output) is not supported: a fetched map is written to a file")
          .Absent({"{dir}/-"}));
  rows.push_back(Case("hbm_hostile_out", {{"hbm", "--out", "b`touch pwned`$(touch pwned).png"}})
                     .OkFiles({"{dir}/b`touch pwned`$(touch pwned).png"}));
  rows.push_back(Case("chirp_hostile_out", {{"chirp", "--duration", "200", "--out", "c`touch pwned`$(touch pwned)"}})
                     .OkFiles({"{dir}/c`touch pwned`$(touch pwned)/frf.png",
                               "{dir}/c`touch pwned`$(touch pwned)/sweep_up_spectrogram.png"}));
  rows.push_back(Case("point_trace_missing_dir", {{"point", "--alpha", "1", "--omega", "1", "--t-end", "20", "--t-keep",
                                                   "10", "--trace", "{dir}/nodir/t.csv"}})
                     .Error("trace")
                     .Absent({"{dir}/nodir"}));
  rows.push_back(Case("point_trace_stdout_and_json", {{"point", "--alpha", "1", "--omega", "1", "--t-end", "20",
                                                       "--t-keep", "10", "--trace", "-", "--json"}})
                     .Error("--trace - writes the trace CSV to standard output, which --json uses too")
                     .Absent({"{dir}/-"}));
  rows.push_back(Case("point_trace_hostile", {{"point", "--alpha", "1", "--omega", "1", "--t-end", "20", "--t-keep",
                                               "10", "--trace", "t`touch pwned`$(touch pwned).csv"}})
                     .OkFiles({"{dir}/t`touch pwned`$(touch pwned).csv"}));
  rows.push_back(
      Case("identify_report_dir_hostile", {Identify("{dir}/ok.csv", {"--report", "r`touch pwned`$(touch pwned)"})})
          .OkFiles({"{dir}/r`touch pwned`$(touch pwned)/residual_force.png",
                    "{dir}/r`touch pwned`$(touch pwned)/record_1.png"})
          .Files({{"{dir}/ok.csv", RecordCsv(200)}}));
  // The record's file name reaches multiplot titles (RenderPanels): newline, backquote, quotes.
  rows.push_back(Case("identify_record_name_hostile",
                      {Identify("{dir}/n\n`touch pwned`$(touch pwned)\"'.csv", {"--report", "{dir}/rep"})})
                     .OkFiles({"{dir}/rep/residual_force.png", "{dir}/rep/record_1.png"})
                     .Files({{"{dir}/n\n`touch pwned`$(touch pwned)\"'.csv", RecordCsv(200)}}));

  // -- 3. gnuplot missing or failing: a clear error, no signal, no file, no temporary left behind.
  {
    Row r =
        OnSweep("gnuplot_missing", png("{dir}/x.png"), Outcome::kError, "cannot start gnuplot", {}, {"{dir}/x.png"});
    r.env = {{"PATH", "{dir}/empty-path"}};
    rows.push_back(r);
  }
  {
    Row r = OnSweep("gnuplot_fails", png("{dir}/x.png"), Outcome::kError, "gnuplot failed", {}, {"{dir}/x.png"});
    r.fake_gnuplot = "cat > /dev/null\necho 'fake gnuplot: no terminal' >&2\nexit 1\n";
    r.env = {{"PATH", "{dir}/fakebin:/usr/bin:/bin"}};
    rows.push_back(r);
  }
  {  // gnuplot closes its stdin at once: the client's write gets EPIPE (SIGPIPE would kill it).
    Row r;
    r.name = "gnuplot_closes_stdin_epipe";
    r.steps = {Identify("{dir}/long.csv", {"--report", "{dir}/rep"})};
    r.outcome = Outcome::kError;
    r.err_has = "gnuplot failed";
    r.absent = {"{dir}/rep/residual_force.png"};
    r.files = {{"{dir}/long.csv", RecordCsv(4000)}};
    r.fake_gnuplot = "exec 0<&-\nsleep 0.2\nexit 0\n";
    r.env = {{"PATH", "{dir}/fakebin:/usr/bin:/bin"}};
    rows.push_back(r);
  }

  // -- 4. Metric names that are not metrics: refused before any HDF5 object is opened.
  const auto metric = [](const std::string& m, const std::string& format = "json") {
    return Map({"--metric", m, "--format", format, "--out", "{dir}/m." + format});
  };
  rows.push_back(
      OnSweep("metric_slash", metric("/"), Outcome::kError, "invalid argument (metric: ", {}, {"{dir}/m.json"}));
  rows.push_back(OnSweep("metric_empty", metric(""), Outcome::kError, "invalid argument (metric: "));
  rows.push_back(OnSweep("metric_dot", metric("."), Outcome::kError, "invalid argument (metric: "));
  rows.push_back(OnSweep("metric_dotdot", metric(".."), Outcome::kError, "invalid argument (metric: "));
  rows.push_back(OnSweep("metric_hdf5_path", metric("/axes/alpha"), Outcome::kError, "allowed: "));
  rows.push_back(OnSweep("metric_axis_scale", metric("alpha"), Outcome::kError, "unknown metric 'alpha'"));
  rows.push_back(OnSweep("metric_newline", metric("frf_db\nlle"), Outcome::kError, "invalid argument (metric: "));
  rows.push_back(OnSweep("metric_traversal", metric("frf_db/../lle"), Outcome::kError, "invalid argument (metric: "));
  rows.push_back(OnSweep("metric_slash_csv", metric("/", "csv"), Outcome::kError, "invalid argument (metric: ", {},
                         {"{dir}/m.csv"}));
  rows.push_back(OnSweep("metric_slash_png", metric("/", "png"), Outcome::kError, "invalid argument (metric: ", {},
                         {"{dir}/m.png"}));
  rows.push_back(OnSweep("metric_typo_suggests", metric("frf"), Outcome::kError, "did you mean 'frf_db'"));

  // -- 5. Queries: bounded length and nesting (the parser recursed into a segfault).
  rows.push_back(OnSweep("query_10k_nested_parens", Query(Repeat("(", 10000) + "lle < 0" + Repeat(")", 10000)),
                         Outcome::kError, "violates length <= 4096"));
  rows.push_back(OnSweep("query_limit_negative", {"query", "{id}", "lle < 1e9", "--data", "{data}", "--limit", "-1"},
                         Outcome::kError,
                         "--limit = -1 violates 0 <= --limit <= 10000000"));  // issue 39: it printed no point at all
  rows.push_back(OnSweep("query_limit_huge",
                         {"query", "{id}", "lle < 1e9", "--data", "{data}", "--json", "--limit", Repeat("9", 4000)},
                         Outcome::kError, "violates 1 <= --limit <= 10000000 with --json"));
  rows.push_back(
      OnSweep("query_10k_open_parens", Query(Repeat("(", 10000)), Outcome::kError, "violates length <= 4096"));
  rows.push_back(OnSweep("query_65_nested_parens", Query(Repeat("(", 65) + "lle < 0" + Repeat(")", 65)),
                         Outcome::kError, "violates depth <= 64"));
  rows.push_back(
      OnSweep("query_64_nested_parens_ok", Query(Repeat("(", 64) + "lle < 0" + Repeat(")", 64)), Outcome::kOk));
  rows.push_back(OnSweep("query_4000_open_parens", Query(Repeat("(", 4000)), Outcome::kError, "violates depth <= 64"));
  rows.push_back(
      OnSweep("query_70_nots", Query(Repeat("not ", 70) + "lle < 0"), Outcome::kError, "violates depth <= 64"));
  rows.push_back(OnSweep("query_too_long", Query(Repeat("lle < 0 or ", 400) + "lle < 0"), Outcome::kError,
                         "violates length <= 4096"));
  rows.push_back(OnSweep("query_long_chain_ok", Query(Repeat("lle < 0 or ", 360) + "lle < 0"), Outcome::kOk));

  // -- 6. Measured data with absurd values; a fit that gives no numbers is an error.
  const auto data_row = [](const std::string& name, const std::string& csv, const std::string& err,
                           std::vector<std::string> extra = {}) {
    return Case(name, {Identify("{dir}/d.csv", std::move(extra))}).Error(err).Files({{"{dir}/d.csv", csv}});
  };
  rows.push_back(data_row("identify_1e300_cell", RecordCsv(200, {{{49, 1}, "1e300"}}),
                          "row 51 column 'x0': 1e300 violates |value| <= 1e+12"));
  rows.push_back(data_row("identify_1e300_everywhere", RecordCsv(200, {}, 1e303), "violates |value| <= 1e+12"));
  rows.push_back(data_row("identify_1e300_time", RecordCsv(200, {{{10, 0}, "1e300"}}), "row 12 column 't'"));
  rows.push_back(data_row("identify_inf_cell", RecordCsv(200, {{{5, 2}, "inf"}}),
                          "row 7 column 'x': 'inf' is not a finite number"));
  rows.push_back(data_row("identify_1e400_cell", RecordCsv(200, {{{5, 2}, "1e400"}}),
                          "row 7 column 'x': '1e400' is not a finite number"));
  rows.push_back(
      data_row("identify_scaled_beyond_bound", RecordCsv(200, {}, 1e9), "x scale", {"--input-scale", "1e7"}));
  rows.push_back(
      data_row("identify_absurd_guess", RecordCsv(200), "identify: the", {"--guess", "main.linear.k_lin=1e308"}));
  rows.push_back(Case("identify_counts_and_params_finite", {Identify("{dir}/d.csv", {"--json"})})
                     .Files({{"{dir}/d.csv", RecordCsv(200)}})
                     .Json(JsonCheck::kIdentifyFinite));

  // -- 7. Measured data as DAQ exports write it, broken: every refusal names the file, row (line),
  //       column or unit and the bound; nothing of the file reaches the terminal raw.
  const std::string plain = RecordCsv(200), body = plain.substr(plain.find('\n') + 1);
  rows.push_back(data_row("identify_line_over_bound", plain + std::string(70000, '7') + "\n",
                          "d.csv row 202: the line is longer than 65536 bytes (violates line length <= 65536)"));
  rows.push_back(data_row("identify_4mb_without_newline", std::string(4 << 20, ','),
                          "d.csv row 1: the line is longer than 65536 bytes"));
  rows.push_back(data_row("identify_unclosed_quote", "t,x0,x\n0,\"0,0\n" + body,
                          "d.csv row 2 column 2: a quote is not closed on its line"));
  rows.push_back(data_row("identify_no_separator", "t x0 x\n" + body, "d.csv row 1 (header): no separator splits it"));
  rows.push_back(data_row("identify_utf16", std::string("\xff\xfet\0,\0x\0\0\n\0", 10), "d.csv is UTF-16 text"));
  rows.push_back(
      data_row("identify_time_in_mm", "t [mm],x0,x\n" + body, "column 't [mm]' (time): 'mm' is a unit of length"));
  rows.push_back(data_row("identify_unknown_time_unit", "t [samples],x0,x\n" + body, "unknown time unit 'samples'"));
  rows.push_back(data_row("identify_unit_and_scale", "t,x0 [mm],x\n" + body,
                          "input_scale = 0.001 would convert it again", {"--input-scale", "0.001"}));
  rows.push_back(data_row("identify_decimal_comma_in_comma_file", "t,x0,x\n0,\"0,5\",0\n" + body,
                          "d.csv row 2 column 'x0': '0,5' is not a finite number"));
  rows.push_back(
      data_row("identify_escape_in_header", "t,x0,\x1b]0;owned\x07\n" + body, "(allowed: t, x0, \\x1b]0;owned\\x07)"));
  {
    std::string wide = "t,x0";
    for (int i = 0; i < 5000; ++i) wide += ",c" + std::to_string(i);
    rows.push_back(data_row("identify_5000_columns_listed_briefly", wide + "\n0,0\n", "... (4938 more)"));
  }
  // Accepted: a DAQ export of the same rows (BOM, CRLF, comments, quoted names with units, ';', decimal comma).
  {
    std::string daq = "\xef\xbb\xbf# export\r\n\"t [s]\";\"x0 (m)\";\"x [m]\"\r\n";
    for (char ch : body) {
      if (ch == ',')
        daq += ';';
      else if (ch == '.')
        daq += ',';
      else if (ch == '\n')
        daq += "\r\n";
      else
        daq += ch;
    }
    rows.push_back(Case("identify_daq_export_ok", {Identify("{dir}/d.csv", {"--json"})})
                       .Files({{"{dir}/d.csv", daq}})
                       .Json(JsonCheck::kIdentifyFinite));
  }
  // -- 7. The output weights and a model file read by --predict: names and bounds in the errors, no shell.
  rows.push_back(data_row("identify_output_weights_shell", RecordCsv(200),
                          "violates output-weights in {residual, noise}",
                          {"--output-weights", "$(touch pwned)`touch pwned`"}));
  rows.push_back(data_row("identify_lm_iterations_zero", RecordCsv(200), "lm-iterations: must be in [1, 10000]",
                          {"--lm-iterations", "0"}));
  rows.push_back(data_row("identify_lm_iterations_beyond_bound", RecordCsv(200), "lm-iterations: must be in [1, 10000]",
                          {"--lm-iterations", "10001"}));
  rows.push_back(data_row("identify_drift_cutoff_negative", RecordCsv(200),
                          "drift-cutoff = -0.5 violates drift-cutoff >= 0 Hz, finite", {"--drift-cutoff", "-0.5"}));
  rows.push_back(data_row("identify_drift_cutoff_nan", RecordCsv(200),
                          "drift-cutoff = nan violates drift-cutoff >= 0 Hz, finite", {"--drift-cutoff", "nan"}));
  rows.push_back(data_row("identify_drift_cutoff_displacement_output", RecordCsv(200), "needs --output-kind velocity",
                          {"--drift-cutoff", "0.5"}));
  // -- 8. Ranges, budgets and threads (session 19 review): strict numbers, named bounds.
  for (const auto& [name, range] :
       std::vector<std::pair<std::string, std::string>>{{"identify_range_scientific", "1e3:2500"},
                                                        {"identify_range_hex", "0x10:2000"},
                                                        {"identify_range_negative_end", "0:-1"},
                                                        {"identify_range_trailing_garbage", "500:2500garbage"},
                                                        {"identify_range_beyond_rows", "0:99999999999"}})
    rows.push_back(data_row(name, RecordCsv(200), "violates range = A:B", {"--range", range}));
  rows.push_back(data_row("identify_test_range_plus_sign", RecordCsv(200), "violates test-range = A:B",
                          {"--test-range", "+5:100"}));
  for (const std::string v : {"nan", "inf", "-5", "1e300"})
    rows.push_back(data_row("identify_max_seconds_" + std::string(v == "-5"      ? "negative"
                                                                  : v == "1e300" ? "huge"
                                                                                 : v),
                            RecordCsv(200), "violates 0 <= max-seconds <= 1e6 s", {"--max-seconds", v}));
  rows.push_back(data_row("identify_threads_negative", RecordCsv(200), "threads = -1 violates threads in [0, 1024]",
                          {"--threads", "-1"}));
  rows.push_back(data_row("identify_threads_huge", RecordCsv(200), "threads = 100000 violates threads in [0, 1024]",
                          {"--threads", "100000"}));
  rows.push_back(
      Case("identify_shooting_horizon_below_four_samples",
           {{"identify", "--data", "{dir}/d.csv", "--terms", "main.linear,main.viscous", "--known", "m_main=1",
             "--max-added", "0", "--global-evals", "0", "--objective", "shooting", "--horizon", "1e-300"}})
          .Error("violates horizon >= 4 samples")
          .Files({{"{dir}/d.csv", RecordCsv(200)}}));
  {
    std::string grouped = "t,x0,x,g\n";
    for (int i = 0; i < 2 * 4100; ++i)
      grouped += std::to_string(i * 0.01) + "," + std::to_string(0.001 * std::sin(i * 0.3)) + "," +
                 std::to_string(0.0012 * std::sin(i * 0.3)) + "," + std::to_string(i / 2) + "\n";
    rows.push_back(data_row("identify_4100_records_in_one_file", grouped, "more than 4096 records in one file",
                            {"--columns", "group=g"}));
  }
  // A file name that is not UTF-8 reaches the JSON (records are named by their files): printed with U+FFFD, and
  // the report's files are written whole.
  rows.push_back(Case("identify_non_utf8_file_name_json", {Identify("{dir}/bad\xff\xfe.csv", {"--json"})})
                     .Files({{"{dir}/bad\xff\xfe.csv", RecordCsv(200)}})
                     .Json(JsonCheck::kIdentifyFinite));
  rows.push_back(
      Case("identify_non_utf8_file_name_report", {Identify("{dir}/bad\xff\xfe.csv", {"--report", "{dir}/rep"})})
          .Files({{"{dir}/bad\xff\xfe.csv", RecordCsv(200)}})
          .OkFiles({"{dir}/rep/report.json", "{dir}/rep/report.md"}));
  {
    const std::string model =
        R"({"final_terms": ["main.linear", "main.viscous"], "params": {"main.linear.k_lin": 100, "main.viscous.c0": 1},
                                  "settings": {"m_main": 1}, "errors_by_output": {"voltage": {"weight": WEIGHT}}})";
    auto with_weight = [&](const std::string& w) { return std::string(model).replace(model.find("WEIGHT"), 6, w); };
    const std::vector<std::string> predict = {"identify",     "--predict", "--model",
                                              "{dir}/m.json", "--data",    "{dir}/d.csv"};
    rows.push_back(Case("identify_predict_weight_beyond_bound", {predict})
                       .Error("model.errors_by_output.voltage.weight = 1e+06 violates 0.01 <= weight <= 100")
                       .Files({{"{dir}/d.csv", RecordCsv(200)}, {"{dir}/m.json", with_weight("1e6")}}));
    rows.push_back(Case("identify_predict_weight_not_a_number", {predict})
                       .Error("model.errors_by_output.voltage.weight")
                       .Files({{"{dir}/d.csv", RecordCsv(200)}, {"{dir}/m.json", with_weight("\"$(touch pwned)\"")}}));
    // The snap-through family's flags (issue 37): refused by name before anything is written.
    rows.push_back(
        Case("identify_synthetic_amplitude_out_of_range",
             {{"identify", "--make-synthetic", "{dir}/syn", "--synthetic", "bistable", "--synthetic-amplitude", "200"}})
            .Error("synthetic-amplitude = 200 violates 0.01 <= value <= 100")
            .Absent({"{dir}/syn"}));
    rows.push_back(Case("identify_synthetic_extra_friction_or_hostile",
                        {{"identify", "--make-synthetic", "{dir}/syn", "--synthetic", "bistable", "--synthetic-extra",
                          "main.friction=1:$(touch pwned)"}})
                       .Error("synthetic-extra")
                       .Absent({"{dir}/syn"}));
    rows.push_back(Case("identify_synthetic_resonator_extra_without_resonator",
                        {{"identify", "--make-synthetic", "{dir}/syn", "--synthetic", "bistable", "--synthetic-extra",
                          "res.stiffness_z3=1e5"}})
                       .Error("needs --synthetic bistable-coupled")
                       .Absent({"{dir}/syn"}));
    rows.push_back(
        Case("identify_predict_model_path_hostile",
             {{"identify", "--predict", "--model", "{dir}/m`touch pwned`$(touch pwned).json", "--data", "{dir}/d.csv"}})
            .Error("model")
            .Files({{"{dir}/d.csv", RecordCsv(200)}}));
  }
  // -- 9. Tokens (issue 39): a control byte in a token (file or $BISTABLE_TOKEN) used to reach gRPC, which
  // logs the metadata (the whole token) and aborts; refused before any call, the token never shown.
  for (const auto& [name, token] :
       std::vector<std::pair<std::string, std::string>>{{"token_file_with_newline", "SECRETA\nSECRETB\n"},
                                                        {"token_file_with_nul", std::string("SECRETA\0SECRETB", 15)},
                                                        {"token_file_with_escape", "SECRETA\x1b[2JSECRETB"},
                                                        {"token_file_with_space", "SECRETA SECRETB"}}) {
    Row r = Case(name, {{"status", "abc", "--coordinator", "127.0.0.1:1", "--token-file", "{dir}/t"}})
                .Error("token-file: the token holds")
                .Files({{"{dir}/t", token}});
    r.err_lacks = "SECRET";
    rows.push_back(r);
  }
  // A good token in plaintext to an address that is not loopback: refused, unless --insecure-remote (then the
  // call is made: 0.0.0.0 is this host, nothing listens on port 1, so it cannot reach it).
  {
    Row r = Case("token_plaintext_to_a_remote_address",
                 {{"status", "abc", "--coordinator", "0.0.0.0:1", "--token-file", "{dir}/t"}})
                .Error("refusing to send the bearer token in plaintext to 0.0.0.0:1")
                .Files({{"{dir}/t", "SECRETAgoodtoken\n"}});
    r.err_lacks = "SECRET";
    rows.push_back(r);
    Row ok = Case("token_plaintext_to_a_remote_address_with_insecure_remote",
                  {{"status", "abc", "--coordinator", "0.0.0.0:1", "--token-file", "{dir}/t", "--insecure-remote"}})
                 .Error("cannot reach 0.0.0.0:1")
                 .Files({{"{dir}/t", "SECRETAgoodtoken\n"}});
    ok.err_lacks = "SECRET";
    rows.push_back(ok);
  }
  rows.push_back(Case("sweeps_data_is_a_file", {{"sweeps", "--data", "/etc/passwd", "--json"}})
                     .Error("data: '/etc/passwd' is not a directory"));
  // -- 12. A diverged point (issue 39): its extremes and energies are undefined (null), not 0.0.
  {
    Row r = Case("point_diverged_extremes_and_energy_are_null",
                 {{"point", "--model", "standalone", "--alpha", "3", "--omega", "3", "--dt", "1", "--t-end", "500",
                   "--t-keep", "250", "--json"}});
    r.out_has = {"\"termination\": \"diverged\"", "\"y_min\": null", "\"y_max\": null", "\"w_in\": null",
                 "\"delta_e\": null"};
    rows.push_back(r);
  }
  // -- 11. Messages stay short (issue 39): a 1 MB unknown key is cut, not echoed whole.
  {
    Row r = Case("spec_key_of_one_megabyte", {{"run", "{dir}/big_key.toml", "--data", "{data}", "--no-plots"}})
                .Error("unknown key 'kkkk")
                .Files({{"{dir}/big_key.toml", "model = \"coupled\"\n" + std::string(1000000, 'k') + " = 1\n"}});
    r.err_max_bytes = 4096;
    rows.push_back(r);
  }
  // -- 10. Numbers and names of service commands (issue 39): refused naming the flag and the bound.
  for (const std::string v : {"nan", "-1", "0", "1e300"})
    rows.push_back(Case("health_timeout_" + std::string(v == "-1"      ? "negative"
                                                        : v == "1e300" ? "huge"
                                                                       : v),
                        {{"health", "--coordinator", "127.0.0.1:1", "--timeout", v}})
                       .Error("violates timeout in (0, 3600] s"));
  rows.push_back(Case("token_name_with_colon", {{"token", "--name", "a:b"}}).Error("name: name 'a:b' violates name"));
  rows.push_back(Case("token_name_with_newline", {{"token", "--name", "a\nb"}}).Error("name 'a\\x0ab' violates name"));
  rows.push_back(Case("token_name_of_65_characters", {{"token", "--name", std::string(65, 'n')}})
                     .Error("at most 64 visible ASCII"));
  {
    Row r = Case("token_env_with_control_byte", {{"sweeps", "--coordinator", "127.0.0.1:1"}})
                .Error("BISTABLE_TOKEN: the token holds a control byte (0x01)");
    r.env = {{"BISTABLE_TOKEN", "SECRETA\x01SECRETB"}};
    r.err_lacks = "SECRET";
    rows.push_back(r);
  }
  AddMarkRows(&rows);
  return rows;
}

// ---- running a row --------------------------------------------------------------------------------

class HostileCli : public ::testing::TestWithParam<Row> {};

// Files named exactly "pwned" (what every hostile command would create), and leftover temporaries.
void ExpectNothingRanAndNothingLeft(const fs::path& dir) {
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const std::string base = it->path().filename().string();
    EXPECT_NE(base, "pwned") << "a command ran: " << it->path();
    EXPECT_NE(base.rfind(".bistable-plot-", 0), 0u) << "temporary plot file left: " << it->path();
    EXPECT_NE(base.rfind(".bistable-out-", 0), 0u) << "temporary output file left: " << it->path();
  }
  EXPECT_FALSE(fs::exists("pwned")) << "a command ran in the test's working directory";
  EXPECT_FALSE(fs::exists("/tmp/pwned")) << "a command ran in /tmp";
}

TEST_P(HostileCli, Row) {
  const Row& row = GetParam();
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", row.name));
  const std::string canary = (dir / "pwned").string();
  const std::string spec_name = ReplaceAll(row.spec_name, "{canary}", canary);
  std::map<std::string, std::string> vars = {{"{dir}", dir.string()},
                                             {"{canary}", canary},
                                             {"{spec}", (dir / "spec.toml").string()},
                                             {"{data}", (dir / "data").string()},
                                             {"{name}", spec_name}};
  auto expand = [&](std::string s) {
    for (const auto& [k, v] : vars) s = ReplaceAll(s, k, v);
    return s;
  };
  if (!row.spec_name.empty()) std::ofstream(dir / "spec.toml") << TinySpec(spec_name);
  for (const auto& [path, content] : row.files) std::ofstream(expand(path), std::ios::binary) << content;
  if (!row.fake_gnuplot.empty()) {
    fs::create_directories(dir / "fakebin");
    const fs::path fake = dir / "fakebin" / "gnuplot";
    std::ofstream(fake) << "#!/bin/sh\n" << row.fake_gnuplot;
    fs::permissions(fake, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec);
  }
  std::map<std::string, std::string> env;
  for (const auto& [k, v] : row.env) env[k] = expand(v);

  bool failed_step = false;
  std::string first_out;
  for (size_t i = 0; i < row.steps.size(); ++i) {
    std::vector<std::string> argv = {BISTABLE_CLI};
    for (const std::string& a : row.steps[i]) argv.push_back(expand(a));
    const ExecResult r = RunArgv(argv, dir.string(), env, 120);
    SCOPED_TRACE("step " + std::to_string(i) + ": " + row.steps[i][0] + "\nstderr: " + r.err);
    ASSERT_FALSE(r.timed_out) << "timed out";
    ASSERT_EQ(r.signal, 0) << "died of signal " << r.signal << " (" << strsignal(r.signal) << ")";
    if (!row.err_lacks.empty()) {
      EXPECT_EQ(r.err.find(row.err_lacks), std::string::npos) << "stderr shows '" << row.err_lacks << "'";
      EXPECT_EQ(r.out.find(row.err_lacks), std::string::npos) << "stdout shows '" << row.err_lacks << "'";
    }
    if (i == 0) {
      first_out = r.out;
      if (row.steps[0][0] == "run" && r.exit_code == 0) {
        const auto j = nlohmann::json::parse(r.out, nullptr, false);
        ASSERT_TRUE(j.is_object() && j.contains("id")) << r.out;
        vars["{id}"] = j["id"].get<std::string>();
      }
    }
    if (r.exit_code != 0) {
      ASSERT_NE(row.outcome, Outcome::kOk) << "exit " << r.exit_code;
      EXPECT_EQ(r.exit_code, 2) << "an error must be exit 2 (bad input)";
      EXPECT_NE(r.err.find("error: "), std::string::npos) << "no 'error: ' line";
      EXPECT_NE(r.err.find(row.err_has), std::string::npos) << "stderr lacks '" << row.err_has << "'";
      if (row.err_max_bytes > 0) {
        EXPECT_LE(r.err.size(), row.err_max_bytes) << "stderr of " << r.err.size() << " bytes";
      }
      failed_step = true;
      break;
    }
    if (i + 1 == row.steps.size()) {
      ASSERT_NE(row.outcome, Outcome::kError)
          << "succeeded; expected an error with '" << row.err_has << "'\nstdout: " << r.out.substr(0, 400);
      for (const std::string& want : row.out_has)
        EXPECT_NE(r.out.find(want), std::string::npos) << "stdout lacks '" << want << "':\n" << r.out;
      if (row.json == JsonCheck::kIdentifyFinite) {
        const auto j = nlohmann::json::parse(r.out, nullptr, false);
        ASSERT_TRUE(j.is_object()) << r.out;
        EXPECT_GE(j["simulations"].get<long long>(), 0);
        for (const auto& [k, v] : j["params"].items()) EXPECT_TRUE(v.is_number()) << k << " = " << v;
        for (const auto& [k, v] : j["params_declared_fit"].items()) EXPECT_TRUE(v.is_number()) << k << " = " << v;
      }
    }
  }
  if (!failed_step) {
    for (const std::string& f : row.ok_files) {
      const std::string p = expand(f);
      EXPECT_TRUE(fs::exists(p)) << "missing: " << p;
      if (fs::exists(p)) {
        EXPECT_GT(fs::file_size(p), 0u) << "empty: " << p;
      }
    }
    if (row.json == JsonCheck::kRunFiles) {
      const auto j = nlohmann::json::parse(first_out, nullptr, false);
      ASSERT_TRUE(j.is_object() && j.contains("files")) << first_out;
      EXPECT_GE(j["files"].size(), 2u) << "the run wrote no plots";
      for (const auto& f : j["files"]) {
        fs::path p = f.get<std::string>();
        if (p.is_relative()) p = dir / p;
        EXPECT_TRUE(fs::exists(p) && fs::file_size(p) > 0) << "missing or empty: " << p;
      }
    }
    if (!row.svg.empty()) {
      std::ifstream in(expand(row.svg));
      const std::string svg((std::istreambuf_iterator<char>(in)), {});
      for (const std::string& s : row.svg_has) {
        const std::string want = XmlEscape(expand(s));
        EXPECT_NE(svg.find(want), std::string::npos) << "the SVG does not show '" << want << "' literally";
      }
    }
  }
  for (const std::string& f : row.absent) EXPECT_FALSE(fs::exists(expand(f))) << "exists: " << expand(f);
  ExpectNothingRanAndNothingLeft(dir);
  if (!HasFailure()) fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Table, HostileCli, ::testing::ValuesIn(Rows()),
                         [](const ::testing::TestParamInfo<Row>& info) { return info.param.name; });

// ---- A full disk (issue 39) ----------------------------------------------------------------------

// `bistable run` on a 2 MB tmpfs, ten times, each on a fresh mount: the 60 x 60 sweep's point cache
// (mostly) fits and its map does not, so the map write meets the full disk. Every run must end with
// exit 2 and the disk-full message (or, when the WAL happened to leave room, succeed) — never a
// signal. Before the fix, HDF5 1.10 kept a map file whose close had failed registered half torn
// down and its exit handler crashed on it: SIGSEGV (139) after the right message, in about half the runs.
TEST(HostileDisk, RunOnATwoMegabyteTmpfsExitsTwoWithTheDiskFullMessageTenTimes) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to mount a small tmpfs";
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", "disk_full"));
  const std::string mnt = (dir / "mnt").string();
  fs::create_directories(mnt);
  std::ofstream(dir / "g60.toml")
      << "model = \"coupled\"\n[axes]\nalpha = { linspace = [0.1, 3, 60] }\n"
         "omega = { linspace = [0.1, 3, 60] }\n[integration]\nt_end = 20.0\nt_keep = 10.0\n";
  int disk_full = 0, map_full = 0;
  for (int run = 0; run < 10; ++run) {
    SCOPED_TRACE("run " + std::to_string(run));
    if (RunArgv({"/bin/mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", mnt}).exit_code != 0)
      GTEST_SKIP() << "cannot mount a tmpfs here";
    const ExecResult r = RunArgv(
        {BISTABLE_CLI, "run", (dir / "g60.toml").string(), "--data", mnt, "--no-plots", "--quiet"}, dir.string());
    RunArgv({"/bin/umount", mnt});
    ASSERT_FALSE(r.timed_out);
    ASSERT_EQ(r.signal, 0) << "died of signal " << r.signal << " (" << strsignal(r.signal) << ")\n" << r.err;
    if (r.exit_code == 0) continue;
    ASSERT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find("disk full"), std::string::npos) << r.err;
    ++disk_full;
    if (r.err.find("(map: ") != std::string::npos) ++map_full;
  }
  std::printf("  10 runs on a 2 MB tmpfs: %d ended disk full, %d of them writing the map\n", disk_full, map_full);
  EXPECT_GE(map_full, 1) << "no run met the full disk while writing its map: the case was not exercised";
  if (!HasFailure()) fs::remove_all(dir);
}

// ---- Modes of what a run creates (issue 39) -----------------------------------------------------

// The data directory was created 0755 and its index and maps 0644: every user of the machine could read
// every result. Created now: the directory and sweeps/ 0750, index.sqlite (and its WAL) and the maps 0640
// (less the umask); a directory that exists keeps its mode.
TEST(HostileFiles, TheDataDirectoryIsCreated0750AndItsIndexAndMaps0640) {
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", "modes"));
  std::ofstream(dir / "spec.toml") << TinySpec("modes");
  const mode_t saved = ::umask(022);  // the common default; the children inherit it
  const ExecResult r = RunArgv({BISTABLE_CLI, "run", (dir / "spec.toml").string(), "--data",
                                (dir / "new" / "data").string(), "--no-plots", "--json"},
                               dir.string());
  fs::create_directories(dir / "old");
  fs::permissions(dir / "old", fs::perms(0755), fs::perm_options::replace);
  const ExecResult r2 = RunArgv(
      {BISTABLE_CLI, "run", (dir / "spec.toml").string(), "--data", (dir / "old").string(), "--no-plots", "--json"},
      dir.string());
  ::umask(saved);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  const auto mode = [](const fs::path& p) {
    struct stat st {};
    return ::stat(p.c_str(), &st) == 0 ? static_cast<int>(st.st_mode & 07777) : -1;
  };
  const std::string id = nlohmann::json::parse(r.out)["id"];
  const fs::path data = dir / "new" / "data";
  EXPECT_EQ(mode(data), 0750) << std::oct << mode(data);
  EXPECT_EQ(mode(data / "sweeps"), 0750) << std::oct << mode(data / "sweeps");
  EXPECT_EQ(mode(data / "index.sqlite"), 0640) << std::oct << mode(data / "index.sqlite");
  EXPECT_EQ(mode(data / "sweeps" / (id + ".h5")), 0640) << std::oct << mode(data / "sweeps" / (id + ".h5"));
  for (const char* side : {"index.sqlite-wal", "index.sqlite-shm"}) {
    if (fs::exists(data / side)) {
      EXPECT_EQ(mode(data / side), 0640) << side << " " << std::oct << mode(data / side);
    }
  }
  EXPECT_EQ(mode(dir / "old"), 0755) << "an existing data directory keeps its mode";
  EXPECT_EQ(mode(dir / "old" / "sweeps"), 0750);
  EXPECT_EQ(mode(dir / "old" / "sweeps" / (id + ".h5")), 0640);
  if (!HasFailure()) fs::remove_all(dir);
}

// ---- Damaged data at start (issue 39) -----------------------------------------------------------
// Each a real `bistable` process on a real data directory whose files the test damages as a crash, a full
// disk or a stray tool would: detected at start (or on a rerun), said naming the file, repaired where it
// can be, and nothing deleted (a damaged file is moved aside to NAME.corrupt-<UTC time>).

struct DataDir {
  fs::path dir, data;
  explicit DataDir(const std::string& name) : dir(bistable_test::FreshDir("hostile", name)), data(dir / "data") {}
  // `bistable run` of TinySpec(name) with one more alpha value: its JSON (exit 0 asserted by the caller).
  ExecResult Run(const std::string& name, const std::string& alpha = "1.0") const {
    std::ofstream(dir / (name + ".toml"))
        << ReplaceAll(TinySpec(name), "alpha = [0.5, 1.0]", "alpha = [0.5, " + alpha + "]");
    return RunArgv(
        {BISTABLE_CLI, "run", (dir / (name + ".toml")).string(), "--data", data.string(), "--no-plots", "--json"},
        dir.string());
  }
  // Two published sweeps, "first" and "second"; false (with the failure added) when a run failed.
  bool TwoPublished(ExecResult* a, ExecResult* b) const {
    *a = Run("first"), *b = Run("second", "1.5");
    EXPECT_EQ(a->exit_code, 0) << a->err;
    EXPECT_EQ(b->exit_code, 0) << b->err;
    return a->exit_code == 0 && b->exit_code == 0;
  }
  ExecResult Cli(std::vector<std::string> args) const {
    args.insert(args.begin(), BISTABLE_CLI);
    args.insert(args.end(), {"--data", data.string()});
    return RunArgv(args, dir.string());
  }
  std::string MapOf(const std::string& run_json) const {
    return (data / "sweeps" / (nlohmann::json::parse(run_json)["id"].get<std::string>() + ".h5")).string();
  }
  // Files of `folder` named `prefix`.corrupt-<time> (not SQLite's -wal and -shm beside them).
  std::vector<fs::path> Aside(const fs::path& folder, const std::string& prefix) const {
    std::vector<fs::path> out;
    for (const auto& e : fs::directory_iterator(folder)) {
      const std::string n = e.path().filename().string();
      if (n.rfind(prefix + ".corrupt-", 0) == 0 && n.find("-wal") == std::string::npos &&
          n.find("-shm") == std::string::npos)
        out.push_back(e.path());
    }
    return out;
  }
};

std::vector<double> Frf(const std::string& map) {
  auto a = bistable::ReadMapMetric(map, "frf_db");
  return a.ok() ? a->values : std::vector<double>{};
}

// A truncated map file followed by a rerun of its sweep: the rerun reported success and served the corrupt
// map. Now the rerun finds it (HDF5's end-of-file check), moves it aside and writes the map again from the
// stored points (nothing computed), saying so.
TEST(HostileFiles, ATruncatedMapIsMovedAsideAndWrittenAgainByARerun) {
  DataDir d("truncated_map");
  const ExecResult first = d.Run("truncated");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const std::string map = d.MapOf(first.out);
  const std::vector<double> good = Frf(map);
  ASSERT_EQ(good.size(), 4u);
  const auto size = fs::file_size(map);
  fs::resize_file(map, size / 2);
  const ExecResult again = d.Run("truncated");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  for (const std::string& want : std::vector<std::string>{"warning: ", "map file '" + map + "' does not open",
                                                          "moved aside to '" + map + ".corrupt-", "planned again"})
    EXPECT_NE(again.err.find(want), std::string::npos) << "stderr lacks '" << want << "':\n" << again.err;
  EXPECT_EQ(Frf(map), good) << "the map was not written again";
  EXPECT_EQ(nlohmann::json::parse(again.out)["computed"], 0) << "the stored points were computed again";
  const auto aside = d.Aside(d.data / "sweeps", fs::path(map).filename().string());
  ASSERT_EQ(aside.size(), 1u);
  EXPECT_EQ(fs::file_size(aside[0]), size / 2) << "the damaged file was not kept as it was";
  const ExecResult third = d.Run("truncated");  // a whole map is served as it is, quietly
  EXPECT_EQ(third.exit_code, 0);
  EXPECT_EQ(third.err.find("warning"), std::string::npos) << third.err;
  if (!HasFailure()) fs::remove_all(d.dir);
}

// A zero-length index.sqlite (SQLite reads it as an empty database) orphaned every published map in
// silence: `sweeps` listed nothing. Now `sweeps` says which map files the index lacks, and the next run (or
// coordinator start) indexes them again from the files' own attributes.
TEST(HostileFiles, AZeroLengthIndexIsRebuiltFromTheMapFiles) {
  DataDir d("empty_index");
  ExecResult a, b;
  ASSERT_TRUE(d.TwoPublished(&a, &b));
  const ExecResult before = d.Cli({"sweeps", "--json"});
  fs::resize_file(d.data / "index.sqlite", 0);
  for (const char* side : {"index.sqlite-wal", "index.sqlite-shm"}) fs::remove(d.data / side);
  const ExecResult listed = d.Cli({"sweeps", "--json"});
  EXPECT_EQ(listed.exit_code, 0) << listed.err;
  const std::string want = "warning: 2 map file(s) of '" + (d.data / "sweeps").string() + "' have no row in '" +
                           (d.data / "index.sqlite").string() + "'";
  EXPECT_NE(listed.err.find(want), std::string::npos) << "stderr lacks '" << want << "':\n" << listed.err;
  const ExecResult rerun = d.Run("first");
  ASSERT_EQ(rerun.exit_code, 0) << rerun.err;
  EXPECT_NE(rerun.err.find("warning: index '" + (d.data / "index.sqlite").string() + "' held no row for 2 map file(s)"),
            std::string::npos)
      << rerun.err;
  EXPECT_EQ(nlohmann::json::parse(rerun.out)["computed"], 0) << "the published sweep was computed again";
  const ExecResult after = d.Cli({"sweeps", "--json"});
  ASSERT_EQ(after.exit_code, 0) << after.err;
  EXPECT_EQ(after.err, "") << "still unindexed maps";
  const auto was = nlohmann::json::parse(before.out), now = nlohmann::json::parse(after.out);
  ASSERT_EQ(now.size(), 2u) << after.out;
  for (size_t i = 0; i < 2; ++i) {
    const auto& w = was[i];
    const auto it = std::find_if(now.begin(), now.end(), [&](const auto& n) { return n["id"] == w["id"]; });
    ASSERT_NE(it, now.end()) << w["id"];
    for (const char* k : {"name", "model", "status", "items_total", "items_done", "file", "maps"})
      EXPECT_EQ((*it)[k], w[k]) << k;
  }
  const ExecResult map = d.Cli({"map", nlohmann::json::parse(b.out)["id"], "--metric", "frf_db"});
  EXPECT_EQ(map.exit_code, 0) << map.err;
  if (!HasFailure()) fs::remove_all(d.dir);
}

// A damaged point cache was used at start without a word. Pages of index.sqlite overwritten (the point
// cache's B-tree root): the next run finds it by SQLite's quick_check, moves the index aside, and makes a new
// one holding what can be read and every published map. Records damaged inside an intact file (checksums
// fail): computed again, and now said.
TEST(HostileFiles, ADamagedIndexIsMovedAsideAndRebuiltAtStart) {
  DataDir d("damaged_index");
  ExecResult a, b;
  ASSERT_TRUE(d.TwoPublished(&a, &b));
  const std::string index = (d.data / "index.sqlite").string(), map_a = d.MapOf(a.out);
  const std::vector<double> good = Frf(map_a);
  // Records damaged in an intact file: their checksums fail.
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(index.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "UPDATE points SET record = zeroblob(length(record))", nullptr, nullptr, nullptr),
              SQLITE_OK);
    sqlite3_close(db);
  }
  fs::remove(map_a);
  const ExecResult recomputed = d.Run("first");
  ASSERT_EQ(recomputed.exit_code, 0) << recomputed.err;
  EXPECT_NE(recomputed.err.find("warning: 4 stored results of sweep " +
                                nlohmann::json::parse(a.out)["id"].get<std::string>() + " failed their checksum in '" +
                                index + "': computed again"),
            std::string::npos)
      << recomputed.err;
  EXPECT_EQ(Frf(map_a), good);
  // Pages overwritten: page 4 is the point cache's root (tables are created in the schema's order).
  {
    std::fstream f(index, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(3 * 4096);
    const std::string junk(4096, '\xab');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  const auto damaged_size = fs::file_size(index);
  const ExecResult rerun = d.Run("first");
  ASSERT_EQ(rerun.exit_code, 0) << rerun.err;
  for (const std::string& want :
       std::vector<std::string>{"warning: index '" + index + "' is damaged", "moved aside to '" + index + ".corrupt-",
                                "published maps of sweeps/"})
    EXPECT_NE(rerun.err.find(want), std::string::npos) << "stderr lacks '" << want << "':\n" << rerun.err;
  const auto aside = d.Aside(d.data, "index.sqlite");
  ASSERT_EQ(aside.size(), 1u);
  EXPECT_EQ(fs::file_size(aside[0]), damaged_size) << "the damaged index was not kept as it was";
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(index.c_str(), &db), SQLITE_OK);
    std::string check;
    sqlite3_exec(
        db, "PRAGMA quick_check",
        [](void* out, int, char** v, char**) {
          *static_cast<std::string*>(out) += v[0] ? v[0] : "";
          return 0;
        },
        &check, nullptr);
    sqlite3_close(db);
    EXPECT_EQ(check, "ok");
  }
  const ExecResult listed = d.Cli({"sweeps", "--json"});
  ASSERT_EQ(listed.exit_code, 0) << listed.err;
  const auto rows = nlohmann::json::parse(listed.out);
  EXPECT_EQ(rows.size(), 2u) << listed.out;
  for (const auto& r : rows) EXPECT_EQ(r["status"], "done") << r;
  EXPECT_EQ(Frf(map_a), good);
  const ExecResult quiet = d.Run("first");
  EXPECT_EQ(quiet.exit_code, 0);
  EXPECT_EQ(quiet.err.find("warning"), std::string::npos) << quiet.err;
  if (!HasFailure()) fs::remove_all(d.dir);
}

// ---- GnuplotString --------------------------------------------------------------------------------

TEST(GnuplotString, SafeTextIsKeptAndEverythingElseIsAFourDigitOctalEscape) {
  EXPECT_EQ(bistable::GnuplotString("alpha = A0/delta_s (x) [1,2] {/Symbol a} -+._:"),
            "\"alpha = A0/delta_s (x) [1,2] {/Symbol a} -+._:\"");
  EXPECT_EQ(bistable::GnuplotString("`id`"), "\"\\0140id\\0140\"");
  EXPECT_EQ(bistable::GnuplotString("a\"b\\c\nd"), "\"a\\0042b\\0134c\\0012d\"");
  EXPECT_EQ(bistable::GnuplotString("@m $x #c ;!'|%&~^"),
            "\"\\0100m \\0044x \\0043c \\0073\\0041\\0047\\0174\\0045\\0046\\0176\\0136\"");
  EXPECT_EQ(bistable::GnuplotString("\xce\xb1"), "\"\\0316\\0261\"");
  EXPECT_EQ(bistable::GnuplotString(std::string("a\0b", 3)), "\"ab\"");  // NUL dropped
  EXPECT_EQ(bistable::GnuplotString(""), "\"\"");
}

TEST(GnuplotString, NoCharacterGnuplotActsOnSurvivesUnescaped) {
  std::string all;
  for (int c = 1; c < 256; ++c) all += static_cast<char>(c);
  const std::string q = bistable::GnuplotString(all);
  ASSERT_GE(q.size(), 2u);
  const std::string body = q.substr(1, q.size() - 2);
  for (char c : std::string("`@$\"'#;!|\n\r%&~^<>?*"))
    EXPECT_EQ(body.find(c), std::string::npos) << "raw '" << c << "'";
  // Every backslash starts a 4-digit octal escape "\0ooo".
  for (size_t p = body.find('\\'); p != std::string::npos; p = body.find('\\', p + 1)) {
    ASSERT_LE(p + 5, body.size());
    EXPECT_EQ(body[p + 1], '0');
    for (int k = 2; k <= 4; ++k) EXPECT_TRUE(body[p + k] >= '0' && body[p + k] <= '7') << body.substr(p, 5);
  }
}

// Axis labels are enhanced text on purpose (symbols); a name that is not a known axis (a file's) is
// shown literally, its markup characters escaped.
TEST(AxisLabel, KnownAxesBecomeSymbolsOtherNamesStayLiteral) {
  EXPECT_EQ(bistable::AxisLabel("alpha", "A0/delta_s"), "α = A_0/δ_s");  // UTF-8 symbols (docs/figures.md)
  EXPECT_EQ(bistable::AxisLabel("omega", "omega0/omega_n"), "Ω = ω_0/ω_n");
  EXPECT_EQ(bistable::AxisLabel("a_b^c{/Symbol x}@&~\\", ""), "a\\_b\\^c\\{/Symbol x\\}\\@\\&\\~\\\\");
}

std::string FindGnuplot() {
  const char* path = std::getenv("PATH");
  std::stringstream ss(path ? path : "/usr/bin:/bin");
  std::string d;
  while (std::getline(ss, d, ':'))
    if (!d.empty() && ::access((d + "/gnuplot").c_str(), X_OK) == 0) return d + "/gnuplot";
  return "";
}

// The claim the escaping rests on, checked against the installed gnuplot (not assumed): what gnuplot
// reads from GnuplotString(s) is s, byte for byte, and nothing in it runs.
TEST(GnuplotString, RoundTripsEveryByteThroughTheInstalledGnuplot) {
  const std::string gnuplot = FindGnuplot();
  ASSERT_FALSE(gnuplot.empty()) << "gnuplot is not installed (scripts/setup.sh)";
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", "roundtrip"));
  const std::string canary = (dir / "pwned").string();
  std::vector<std::string> cases;
  std::string every;
  for (int c = 1; c < 256; ++c) every += static_cast<char>(c), every += '7';  // an octal digit after each escape
  cases.push_back(every);
  cases.push_back("`touch " + canary + "`");
  cases.push_back("$(touch " + canary + ")");
  cases.push_back("x\nsystem(\"touch " + canary + "\")\n!touch " + canary);
  cases.push_back("@GPVAL_TERM @x");
  cases.push_back("\"; system(\"touch " + canary + "\"); print \"");
  cases.push_back("\\0601 \\140 \\\\ \\");
  cases.push_back("\xce\xb1\xce\xb2 \xe2\x9c\x93");
  std::string script = "set terminal dumb\nset output '/dev/null'\n";
  for (size_t i = 0; i < cases.size(); ++i)
    script += "set print " + bistable::GnuplotString((dir / ("out" + std::to_string(i))).string()) + "\nprint " +
              bistable::GnuplotString(cases[i]) + "\nunset print\n";
  std::ofstream(dir / "script.gp") << script;
  const ExecResult r = RunArgv({gnuplot, (dir / "script.gp").string()}, dir.string());
  ASSERT_EQ(r.signal, 0);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (size_t i = 0; i < cases.size(); ++i) {
    std::ifstream in(dir / ("out" + std::to_string(i)), std::ios::binary);
    const std::string got((std::istreambuf_iterator<char>(in)), {});
    EXPECT_EQ(got, cases[i] + "\n") << "case " << i;
  }
  EXPECT_FALSE(fs::exists(canary)) << "a command ran";
  if (!HasFailure()) fs::remove_all(dir);
}

// ---- the library entry points, in this process (SIGPIPE is not ignored here) ---------------------

bistable::PlotData Heatmap(const std::string& title, int n) {
  bistable::PlotData d;
  d.title = title;
  d.metric = "lle";
  d.axis_names = {"alpha", "omega"};
  d.axis_units = {"A0/delta_s", "omega0/omega_n"};
  std::vector<double> v;
  for (int i = 0; i < n; ++i) v.push_back(0.1 + i);
  d.axis_values = {v, v};
  for (int i = 0; i < n * n; ++i) d.values.push_back(std::sin(i * 0.1));
  return d;
}

TEST(RenderPlot, MissingDirectoryIsInvalidArgumentNamingOut) {
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", "render_missing"));
  const bistable::Status st = bistable::RenderPlot(Heatmap("t", 3), (dir / "no" / "x.png").string());
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), bistable::Status::Code::kInvalidArgument);
  EXPECT_EQ(st.field(), "out");
  EXPECT_FALSE(fs::exists(dir / "no"));
  fs::remove_all(dir);
}

TEST(RenderPlot, HostileTitleIsShownLiterally) {
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", "render_title"));
  const std::string canary = (dir / "pwned").string();
  const std::string title = "t `touch " + canary + "` $(touch " + canary + ") @m \"q' \\ \xce\xb1";
  const bistable::Status st = bistable::RenderPlot(Heatmap(title, 3), (dir / "x.svg").string());
  ASSERT_TRUE(st.ok()) << st.ToString();
  std::ifstream in(dir / "x.svg");
  const std::string svg((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(svg.find(XmlEscape(title)), std::string::npos);
  EXPECT_FALSE(fs::exists(canary));
  ExpectNothingRanAndNothingLeft(dir);
  fs::remove_all(dir);
}

// A gnuplot that stops reading at once while a large script is written: without SIGPIPE blocked
// around the write this test process would die (it does not ignore SIGPIPE).
TEST(RenderPlot, GnuplotThatStopsReadingIsAnErrorNotSigpipe) {
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", "render_epipe"));
  fs::create_directories(dir / "bin");
  std::ofstream(dir / "bin" / "gnuplot") << "#!/bin/sh\nexec 0<&-\nsleep 0.2\nexit 0\n";
  fs::permissions(dir / "bin" / "gnuplot", fs::perms::owner_all);
  const char* old = std::getenv("PATH");
  const std::string saved = old ? old : "";
  ::setenv("PATH", ((dir / "bin").string() + ":/usr/bin:/bin").c_str(), 1);
  const bistable::Status st = bistable::RenderPlot(Heatmap("big", 150), (dir / "x.png").string());  // ~0.6 MB of script
  ::setenv("PATH", saved.c_str(), 1);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("gnuplot failed"), std::string::npos) << st.ToString();
  EXPECT_FALSE(fs::exists(dir / "x.png"));
  ExpectNothingRanAndNothingLeft(dir);
  fs::remove_all(dir);
}

TEST(RenderPlot, MissingGnuplotIsAClearError) {
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", "render_nognuplot"));
  const char* old = std::getenv("PATH");
  const std::string saved = old ? old : "";
  ::setenv("PATH", (dir / "nothing-here").c_str(), 1);
  const bistable::Status st = bistable::RenderPlot(Heatmap("t", 3), (dir / "x.png").string());
  ::setenv("PATH", saved.c_str(), 1);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("cannot start gnuplot"), std::string::npos) << st.ToString();
  ExpectNothingRanAndNothingLeft(dir);
  fs::remove_all(dir);
}

// ReadMapMetric is what the coordinator calls with a remote client's metric string (NUL included,
// which no command line can carry).
TEST(ReadMapMetric, RefusesNamesThatAreNotMetricsOfTheMap) {
  const fs::path dir = fs::path(bistable_test::FreshDir("hostile", "readmetric"));
  std::ofstream(dir / "spec.toml") << TinySpec("plain");
  const ExecResult r = RunArgv({BISTABLE_CLI, "run", (dir / "spec.toml").string(), "--data", (dir / "data").string(),
                                "--json", "--quiet", "--no-plots"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  fs::path h5 = nlohmann::json::parse(r.out)["files"][0].get<std::string>();
  if (h5.is_relative()) h5 = fs::current_path() / h5;
  for (const std::string& bad :
       {std::string("/"), std::string(""), std::string("."), std::string(".."), std::string("/axes/alpha"),
        std::string("alpha"), std::string("omega"), std::string("frf_db\0lle", 10), std::string("frf_db\n"),
        std::string("frf_db/."), std::string("../frf_db"), std::string(100000, 'a')}) {
    auto m = bistable::ReadMapMetric(h5.string(), bad);
    ASSERT_FALSE(m.ok()) << "'" << bad << "' was read";
    EXPECT_EQ(m.status().code(), bistable::Status::Code::kInvalidArgument) << m.status().ToString();
    EXPECT_EQ(m.status().field(), "metric");
    EXPECT_LT(m.status().message().size(), 2000u) << "the message echoes the whole name";
  }
  auto good = bistable::ReadMapMetric(h5.string(), "frf_db");
  ASSERT_TRUE(good.ok()) << good.status().ToString();
  EXPECT_EQ(good->values.size(), 4u);
  fs::remove_all(dir);
}

}  // namespace
