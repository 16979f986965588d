#include "ptda/cli/evaluate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>

#include "ptda/cli/jsonl.hpp"
#include "ptda/cli/svg_plot.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {

namespace {

constexpr std::array<const char*, 2> kFeatureNames = {"rms_res", "entropy_res"};

// One member of a monitor line, with the error naming the line.
const JsonValue& member(const JsonValue& row, const char* key, const std::string& where) {
  if (row.kind != JsonValue::Kind::kObject) throw Error(where + ": not a JSON object");
  const auto it = row.object.find(key);
  if (it == row.object.end()) throw Error(where + ": missing field \"" + key + "\"");
  return it->second;
}

bool bool_member(const JsonValue& row, const char* key, const std::string& where) {
  const JsonValue& v = member(row, key, where);
  if (v.kind != JsonValue::Kind::kBool) throw Error(where + ": field \"" + key + "\" is not true/false");
  return v.boolean;
}

const std::string& string_member(const JsonValue& row, const char* key, const std::string& where) {
  const JsonValue& v = member(row, key, where);
  if (v.kind != JsonValue::Kind::kString) throw Error(where + ": field \"" + key + "\" is not a string");
  return v.string;
}

double finite_member(const JsonValue& row, const char* key, const std::string& where) {
  const JsonValue& v = member(row, key, where);
  if (v.kind != JsonValue::Kind::kNumber || !std::isfinite(v.number)) {
    throw Error(where + ": scored window without a finite \"" + key + "\"");
  }
  return v.number;
}

double mean_of(std::span<const double> v) {
  double s = 0.0;
  for (const double x : v) s += x;
  return s / static_cast<double>(v.size());
}

FeatureSeparation separation(const char* name, std::span<const double> healthy,
                             std::span<const double> faulty) {
  FeatureSeparation f;
  f.feature = name;
  f.mean_healthy = mean_of(healthy);
  f.mean_faulty = mean_of(faulty);
  f.ratio = f.mean_faulty / f.mean_healthy;
  f.auc = roc_auc(healthy, faulty);
  f.separability = std::max(f.auc, 1.0 - f.auc);
  f.direction = f.auc > 0.5 ? Direction::kHigher : (f.auc < 0.5 ? Direction::kLower : Direction::kNone);
  return f;
}

SetSummary summary_of(const MonitorWindows& w) {
  SetSummary s;
  s.windows = w.windows;
  s.scored = w.scored();
  s.abnormal = w.abnormal;
  s.alarm_windows = w.alarm_windows;
  return s;
}

std::string set_json(const SetSummary& s) {
  JsonObject o;
  o.add("windows", static_cast<std::uint64_t>(s.windows))
      .add("scored", static_cast<std::uint64_t>(s.scored))
      .add("abnormal", static_cast<std::uint64_t>(s.abnormal))
      .add("detection_rate", s.detection_rate())
      .add("alarm_windows", static_cast<std::uint64_t>(s.alarm_windows))
      .add("alarm", s.alarm());
  return o.str();
}

std::string feature_json(const FeatureSeparation& f) {
  JsonObject o;
  o.add("mean_healthy", f.mean_healthy)
      .add("mean_faulty", f.mean_faulty)
      .add("ratio", f.ratio)
      .add("auc", f.auc)
      .add("separability", f.separability)
      .add("direction", direction_name(f.direction));
  return o.str();
}

// Splices already-serialised objects into a JSON object text: {"a":<a>,"b":<b>}.
std::string with_members(std::string object,
                         const std::vector<std::pair<std::string, std::string>>& members) {
  object.pop_back();  // '}'
  for (const auto& [k, v] : members) {
    if (object.size() > 1) object.push_back(',');
    object += json_string(k) + ":" + v;
  }
  return object + "}";
}

std::string percent(double fraction) {
  return fixed(100.0 * fraction, 1) + " %";
}

}  // namespace

void read_monitor_jsonl(const std::string& path, MonitorWindows& into) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(path + ": cannot open");
  std::string line;
  std::size_t line_no = 0;
  while (std::getline(f, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    const std::string where = path + ":" + std::to_string(line_no);
    const JsonValue row = parse_json(line, where);
    const std::string& method = string_member(row, "method", where);
    if (into.method.empty()) {
      into.method = method;
    } else if (method != into.method) {
      throw Error(where + ": method \"" + method + "\" differs from \"" + into.method +
                  "\" of the windows read before (evaluate one method at a time)");
    }
    ++into.windows;
    const std::string& status = string_member(row, "status", where);
    if (bool_member(row, "alarm", where)) ++into.alarm_windows;
    if (status != "scored") continue;
    into.rms_res.push_back(finite_member(row, "rms_res", where));
    into.entropy_res.push_back(finite_member(row, "entropy_res", where));
    if (bool_member(row, "abnormal", where)) ++into.abnormal;
  }
  if (f.bad()) throw Error(path + ": read error");
}

double roc_auc(std::span<const double> healthy, std::span<const double> faulty) {
  if (healthy.empty() || faulty.empty())
    throw Error("ROC AUC: needs at least one healthy and one faulty value");
  std::vector<double> h(healthy.begin(), healthy.end());
  for (const double v : h) {
    if (std::isnan(v)) throw Error("ROC AUC: a healthy value is NaN");
  }
  std::sort(h.begin(), h.end());
  // twice_u = 2 U = sum over faulty f of 2 #{h < f} + #{h == f}: an exact integer.
  std::uint64_t twice_u = 0;
  for (const double v : faulty) {
    if (std::isnan(v)) throw Error("ROC AUC: a faulty value is NaN");
    const auto lo = std::lower_bound(h.begin(), h.end(), v);
    const auto hi = std::upper_bound(lo, h.end(), v);
    twice_u += 2 * static_cast<std::uint64_t>(lo - h.begin()) + static_cast<std::uint64_t>(hi - lo);
  }
  return static_cast<double>(twice_u) /
         (2.0 * static_cast<double>(h.size()) * static_cast<double>(faulty.size()));
}

const char* direction_name(Direction d) noexcept {
  switch (d) {
    case Direction::kHigher:
      return "higher";
    case Direction::kLower:
      return "lower";
    case Direction::kNone:
      break;
  }
  return "none";
}

Evaluation evaluate_separation(const MonitorWindows& healthy, const MonitorWindows& faulty,
                               const std::string& healthy_source, const std::string& faulty_source) {
  if (healthy.scored() == 0) {
    throw Error(healthy_source + ": no scored windows in the healthy set (" +
                std::to_string(healthy.windows) + " windows read)");
  }
  if (faulty.scored() == 0) {
    throw Error(faulty_source + ": no scored windows in the faulty set (" + std::to_string(faulty.windows) +
                " windows read)");
  }
  if (healthy.method != faulty.method) {
    throw Error("method mismatch: " + healthy_source + " holds \"" + healthy.method + "\" windows but " +
                faulty_source + " holds \"" + faulty.method + "\"");
  }
  Evaluation e;
  e.method = healthy.method;
  e.healthy = summary_of(healthy);
  e.faulty = summary_of(faulty);
  e.features[0] = separation(kFeatureNames[0], healthy.rms_res, faulty.rms_res);
  e.features[1] = separation(kFeatureNames[1], healthy.entropy_res, faulty.entropy_res);
  return e;
}

std::string evaluation_json(const Evaluation& e) {
  JsonObject o;
  o.add("label", e.label);
  if (e.x) {
    o.add("x", *e.x);
  } else {
    o.add_null("x");
  }
  o.add("method", e.method);
  return with_members(o.str(), {{"healthy", set_json(e.healthy)},
                                {"faulty", set_json(e.faulty)},
                                {e.features[0].feature, feature_json(e.features[0])},
                                {e.features[1].feature, feature_json(e.features[1])}});
}

Evaluation parse_evaluation_json(const std::string& text, const std::string& source) {
  const JsonValue v = parse_json(text, source);
  Evaluation e;
  e.label = string_member(v, "label", source);
  const JsonValue& x = member(v, "x", source);
  if (!x.is_null()) {
    if (x.kind != JsonValue::Kind::kNumber) throw Error(source + ": field \"x\" is not a number");
    e.x = x.number;
  }
  e.method = string_member(v, "method", source);
  const auto read_set = [&](const char* key) {
    const JsonValue& s = member(v, key, source);
    const std::string where = source + ": " + key;
    SetSummary r;
    r.windows = static_cast<std::size_t>(finite_member(s, "windows", where));
    r.scored = static_cast<std::size_t>(finite_member(s, "scored", where));
    r.abnormal = static_cast<std::size_t>(finite_member(s, "abnormal", where));
    r.alarm_windows = static_cast<std::size_t>(finite_member(s, "alarm_windows", where));
    return r;
  };
  e.healthy = read_set("healthy");
  e.faulty = read_set("faulty");
  for (std::size_t i = 0; i < kFeatureNames.size(); ++i) {
    const JsonValue& f = member(v, kFeatureNames[i], source);
    const std::string where = source + ": " + kFeatureNames[i];
    FeatureSeparation& out = e.features[i];
    out.feature = kFeatureNames[i];
    out.mean_healthy = finite_member(f, "mean_healthy", where);
    out.mean_faulty = finite_member(f, "mean_faulty", where);
    const JsonValue& ratio = member(f, "ratio", where);
    out.ratio = ratio.kind == JsonValue::Kind::kNumber ? ratio.number : std::nan("");
    out.auc = finite_member(f, "auc", where);
    out.separability = std::max(out.auc, 1.0 - out.auc);
    out.direction =
        out.auc > 0.5 ? Direction::kHigher : (out.auc < 0.5 ? Direction::kLower : Direction::kNone);
  }
  return e;
}

std::string evaluation_text(const Evaluation& e) {
  std::string s = "evaluate";
  if (!e.label.empty()) s += " " + e.label;
  s += " (" + e.method + "): healthy " + std::to_string(e.healthy.scored) + " scored of " +
       std::to_string(e.healthy.windows) + " windows, faulty " + std::to_string(e.faulty.scored) +
       " scored of " + std::to_string(e.faulty.windows) + "\n";
  for (const auto& f : e.features) {
    s += "  " + pad_right(f.feature, 12) + "mean healthy " + general(f.mean_healthy, 6) + ", faulty " +
         general(f.mean_faulty, 6) + ", ratio " + general(f.ratio, 5) + ", AUC " + fixed(f.auc, 4) +
         " (separability " + fixed(f.separability, 4) + ", faulty " + direction_name(f.direction) + ")\n";
  }
  const auto set_line = [](const char* name, const SetSummary& set) {
    return std::string("  ") + name + "abnormal " + std::to_string(set.abnormal) + " of " +
           std::to_string(set.scored) + " (" + percent(set.detection_rate()) + "), alarm " +
           (set.alarm() ? "raised in " + std::to_string(set.alarm_windows) + " windows"
                        : std::string("never raised")) +
           "\n";
  };
  s += set_line("healthy     ", e.healthy);
  s += set_line("faulty      ", e.faulty);
  return s;
}

std::string evaluation_markdown_header() {
  return "| case | method | scored h / f | RMS ratio f/h | RMS AUC | entropy ratio f/h | entropy AUC | "
         "abnormal h | "
         "abnormal f | alarm h / f |\n"
         "|---|---|---:|---:|---:|---:|---:|---:|---:|---|\n";
}

std::string evaluation_markdown_row(const Evaluation& e) {
  const auto& r = e.features[0];
  const auto& h = e.features[1];
  const auto yn = [](bool b) { return b ? std::string("yes") : std::string("no"); };
  return "| " + e.label + " | " + e.method + " | " + std::to_string(e.healthy.scored) + " / " +
         std::to_string(e.faulty.scored) + " | " + fixed(r.ratio, 4) + " | " + fixed(r.auc, 3) + " | " +
         fixed(h.ratio, 4) + " | " + fixed(h.auc, 3) + " | " + percent(e.healthy.detection_rate()) + " | " +
         percent(e.faulty.detection_rate()) + " | " + yn(e.healthy.alarm()) + " / " + yn(e.faulty.alarm()) +
         " |\n";
}

std::string auc_plot_svg(std::span<const Evaluation> results, const std::string& feature,
                         const std::string& title, const std::string& x_label) {
  std::size_t fi = kFeatureNames.size();
  for (std::size_t i = 0; i < kFeatureNames.size(); ++i) {
    if (feature == kFeatureNames[i]) fi = i;
  }
  if (fi == kFeatureNames.size())
    throw Error("AUC plot: unknown feature '" + feature + "' (rms_res or entropy_res)");
  struct MethodStyle {
    const char* method;
    const char* label;
    const char* color;
  };
  constexpr std::array<MethodStyle, 3> kMethods = {
      {{"raw", "raw", "#1f77b4"}, {"tda", "TDA", "#ff7f0e"}, {"ptda", "PTDA", "#2ca02c"}}};
  std::map<std::string, std::vector<std::pair<double, double>>> points;
  for (const auto& e : results) {
    if (!e.x) throw Error("AUC plot: result '" + e.label + "' (" + e.method + ") has no x value");
    points[e.method].emplace_back(*e.x, e.features[fi].auc);
  }
  svg::Plot plot;
  plot.title = title;
  plot.x_label = x_label;
  plot.y_label = feature + " ROC AUC";
  // A little room around [0, 1] so markers at AUC 0 and 1 are drawn whole.
  plot.y_min = -0.05;
  plot.y_max = 1.05;
  for (const auto& m : kMethods) {
    auto it = points.find(m.method);
    if (it == points.end()) continue;
    std::sort(it->second.begin(), it->second.end());
    for (const auto kind : {svg::Series::Kind::kLine, svg::Series::Kind::kMarkers}) {
      svg::Series s;
      s.label = kind == svg::Series::Kind::kLine ? m.label : "";
      s.color = m.color;
      s.kind = kind;
      s.width_px = kind == svg::Series::Kind::kLine ? 1.5 : 3.0;
      for (const auto& [x, y] : it->second) {
        s.x.push_back(x);
        s.y.push_back(y);
      }
      plot.series.push_back(std::move(s));
    }
  }
  plot.bands.push_back({0.5, 0.5, "chance", "#7f7f7f"});
  return svg::render_svg(plot, svg::PlotStyle{460, 240, 62, 12, 38, 40, 11});
}

}  // namespace ptda::cli
