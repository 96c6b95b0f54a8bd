// Record markers on map figures (`bistable map ID --metric M --format png|svg|pdf --mark X,Y,LABEL`,
// `--marks FILE.csv`): where measurements were taken and what they showed, drawn on the heatmap
// (PlotData::marks). X is on the figure's horizontal axis (the slice's second free axis: omega on an alpha x
// omega map), Y on its vertical axis (the first free axis: alpha), in the axes' units.
//
// Everything here comes from the user and reaches gnuplot, so it is bounded and checked before any map is
// read (docs/limits.md): at most limits::kMaxMapMarks marks in all, numbers finite, a label at most
// limits::kMaxMarkLabelChars characters of printable UTF-8 (no control characters, no line or paragraph
// separators, no bidirectional controls). A label is plain text: it enters the script only through
// GnuplotString and is drawn noenhanced, so quotes, backquotes, @, $ and markup show as themselves. Errors
// are InvalidArgument naming the flag ("mark" or "marks") and the bound.
#ifndef BISTABLE_CLIENT_MAP_MARKS_H_
#define BISTABLE_CLIENT_MAP_MARKS_H_

#include <string>
#include <vector>

#include "base/status.h"
#include "client/plot.h"

namespace bistable {

struct MapMark {
  double x = 0, y = 0;  // horizontal, vertical
  std::string label;
  std::string field;   // "mark" or "marks": the flag it came from
  std::string origin;  // for messages: "--mark '1,2,A'" or "--marks 'm.csv' line 3"
};

// One mark from "X,Y,LABEL": split at the first two commas (the label may hold commas); spaces around X, Y
// and the label are dropped; a label wholly in double quotes is unquoted CSV-style ("" is one quote); an
// empty label draws the point alone.
StatusOr<MapMark> ParseMark(const std::string& text, const std::string& field, const std::string& origin);

// The marks of every --mark (in order), then of the --marks file (none when `file` is empty): rows
// x,y,label; a first row "x,y,label" (any case) is a header; blank lines and lines starting with '#' are
// skipped; "\r\n" line ends and a UTF-8 byte-order mark are accepted. The file is a regular file of at
// most limits::kMaxMarksFileBytes.
StatusOr<std::vector<MapMark>> ParseMarks(const std::vector<std::string>& marks, const std::string& file);

// The marks onto figure `d`: refused when it is not a heatmap (one free axis), or when a mark lies outside
// the range the heatmap draws (HeatmapAxisRange: its grid values and half a grid step beyond each end),
// the message naming the axis, its grid values' range and the drawn range.
Status AddMarks(const std::vector<MapMark>& marks, PlotData* d);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_MAP_MARKS_H_
