#include "ptda/cli/history_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <optional>

#include "ptda/cli/jsonl.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {
namespace {

namespace fs = std::filesystem;

/// The history files, oldest first: history.<k>.jsonl by falling k, then history.jsonl.
std::vector<fs::path> history_files(const fs::path& dir) {
  std::vector<std::pair<unsigned long, fs::path>> rotated;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("history.", 0) != 0 || name.size() <= 14 || name.substr(name.size() - 6) != ".jsonl")
      continue;
    const std::string mid = name.substr(8, name.size() - 14);
    if (mid.empty() || mid.find_first_not_of("0123456789") != std::string::npos) continue;
    rotated.emplace_back(std::strtoul(mid.c_str(), nullptr, 10), e.path());
  }
  if (ec) throw Error(dir.string() + ": cannot read the directory: " + ec.message());
  std::sort(rotated.begin(), rotated.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<fs::path> out;
  for (auto& r : rotated) out.push_back(std::move(r.second));
  if (fs::exists(dir / "history.jsonl")) out.push_back(dir / "history.jsonl");
  if (out.empty()) {
    throw Error(dir.string() + ": no history.jsonl (is this a [history] dir of ptdad? docs/fleet.md)");
  }
  return out;
}

/// "2026-11-27T04:20:31.125Z" -> seconds since the epoch (UTC); nullopt when not that form.
std::optional<double> utc_seconds(const std::string& t) {
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, s = 0, ms = 0;
  if (t.size() != 24 ||
      std::sscanf(t.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d.%3dZ", &y, &mo, &d, &h, &mi, &s, &ms) != 7) {
    return std::nullopt;
  }
  // Days from civil (proleptic Gregorian), H. Hinnant's algorithm.
  y -= mo <= 2 ? 1 : 0;
  const int era = (y >= 0 ? y : y - 399) / 400;
  const int yoe = y - era * 400;
  const int doy = (153 * (mo + (mo > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  const double days = static_cast<double>(era) * 146097.0 + doe - 719468.0;
  return days * 86400.0 + h * 3600.0 + mi * 60.0 + s + ms / 1000.0;
}

/// What the report needs of one line (a whole JsonValue per line would take ~6 KB: a 128 MiB history
/// would need over 1 GB).
struct Line {
  double t_unix = 0.0;
  bool state = false;
  std::string t_utc;
  std::string text;  ///< state: the note; window: the method
  std::string joint;
  bool scored = false, abnormal = false, alarm = false;
  std::int32_t segment = -1;
  std::uint32_t n = 0;
  double rms = 0.0, entropy = 0.0, duration_s = 0.0;
  dsp::FeatureThresholds th;
};

Line compact(const JsonValue& v, double t_unix) {
  Line l;
  l.t_unix = t_unix;
  l.t_utc = v.at("t_utc").as_string();
  if (v.object.count("joint") != 0) l.joint = v.at("joint").as_string();
  if (v.at("type").as_string() == "state") {
    l.state = true;
    const std::string& causes = v.at("causes").as_string();
    const std::string& reason = v.at("reason").as_string();
    l.text = l.t_utc + ": " + v.at("state").as_string() + " (" + v.at("phase").as_string() + "), level " +
             v.at("level").as_string() + (causes == "none" ? std::string() : ", cause " + causes) +
             (reason.empty() ? std::string() : ": " + reason);
    return l;
  }
  l.text = v.at("method").as_string();
  l.alarm = v.at("alarm").as_bool();
  l.scored = v.at("status").as_string() == "scored";
  if (!l.scored) return l;
  l.n = static_cast<std::uint32_t>(v.at("n").as_number());
  l.segment = static_cast<std::int32_t>(v.at("segment").as_number());
  l.rms = v.at("rms_res").as_number();
  l.entropy = v.at("entropy_res").as_number();
  l.abnormal = v.at("abnormal").as_bool();
  l.duration_s = v.at("t_end").as_number() - v.at("t_start").as_number();
  l.th.rms = {v.at("rms_band").array.at(0).as_number(), v.at("rms_band").array.at(1).as_number()};
  l.th.entropy = {v.at("entropy_band").array.at(0).as_number(), v.at("entropy_band").array.at(1).as_number()};
  return l;
}

}  // namespace

ReportData history_report_data(const fs::path& dir, const HistoryReadOptions& opt) {
  std::vector<Line> lines;
  std::vector<std::string> notes;
  const std::vector<fs::path> files = history_files(dir);
  std::size_t partial = 0, unreadable = 0;
  std::string first_unreadable;
  for (std::size_t f = 0; f < files.size(); ++f) {
    std::ifstream in(files[f], std::ios::binary);
    if (!in) throw Error(files[f].string() + ": cannot open");
    std::string text;
    std::size_t no = 0;
    while (std::getline(in, text)) {
      ++no;
      if (text.empty()) continue;
      const bool last_of_newest = f + 1 == files.size() && in.peek() == std::char_traits<char>::eof();
      const std::string where = files[f].string() + ":" + std::to_string(no);
      try {
        const JsonValue v = parse_json(text, where);
        if (v.kind != JsonValue::Kind::kObject) throw Error(where + ": not a JSON object");
        const std::string& type = v.at("type").as_string();
        if (type != "window" && type != "state") throw Error(where + ": unknown \"type\" \"" + type + "\"");
        const JsonValue& t = v.at("t_utc");
        const std::optional<double> ts = t.is_null() ? std::nullopt : utc_seconds(t.as_string());
        if (!ts) {
          if (type == "state") throw Error(where + ": \"t_utc\" is not a UTC time");
          continue;  // a window without wall time cannot be placed on the time axis
        }
        if (opt.last_hours <= 0.0 || lines.empty() || *ts >= lines.back().t_unix - opt.last_hours * 3600.0) {
          lines.push_back(compact(v, *ts));
        }
      } catch (const Error& e) {
        if (last_of_newest && text.back() != '}') {  // cut by a power loss while being written
          ++partial;
          continue;
        }
        // One unreadable line does not make a week of history unreadable: left out, said where.
        if (unreadable++ == 0) first_unreadable = e.what();
      }
    }
  }
  if (partial > 0) {
    notes.push_back("left out a partial last line of " + files.back().string() +
                    " (written while the power failed?)");
  }
  if (unreadable > 0) {
    notes.push_back("left out " + std::to_string(unreadable) +
                    " unreadable line(s); the first: " + first_unreadable);
  }
  if (lines.empty()) throw Error(dir.string() + ": the history has no line with a time");
  std::stable_sort(lines.begin(), lines.end(),
                   [](const Line& a, const Line& b) { return a.t_unix < b.t_unix; });
  double t_first = lines.front().t_unix;
  const double t_last = lines.back().t_unix;
  if (opt.last_hours > 0.0) {
    t_first = std::max(t_first, t_last - opt.last_hours * 3600.0);
    std::erase_if(lines, [&](const Line& l) { return l.t_unix < t_first; });
  }

  ReportData data;
  data.from_history = true;
  std::string joint;
  std::map<std::string, MethodTrend> trends;
  std::uint64_t windows = 0, judged = 0, abnormal = 0, alarm_windows = 0;
  std::optional<std::string> first_alarm;
  double window_h = 0.0;
  std::vector<std::string> state_notes;
  for (const Line& l : lines) {
    if (joint.empty()) joint = l.joint;
    if (l.state) {
      state_notes.push_back(l.text);
      continue;
    }
    ++windows;
    if (l.alarm) {
      ++alarm_windows;
      if (!first_alarm) first_alarm = l.t_utc;
    }
    if (!l.scored) continue;
    ++judged;
    MethodTrend& tr = trends[l.text];
    tr.method = l.text;
    TrendPoint p;
    p.t_s = (l.t_unix - t_first) / 3600.0;  // hours: the trend axis of a history
    p.window_seq = l.n;
    p.class_id = l.segment;
    p.rms_res = l.rms;
    p.entropy_res = l.entropy;
    p.abnormal = l.abnormal;
    p.alarm = l.alarm;
    p.recording = "history";
    if (p.abnormal) ++abnormal;
    tr.points.push_back(p);
    window_h = std::max(window_h, l.duration_s / 3600.0);
    // The band each class was last judged against (a reload with a new baseline moves it).
    auto it = std::find_if(tr.class_thresholds.begin(), tr.class_thresholds.end(),
                           [&](const auto& c) { return c.first == p.class_id; });
    if (it == tr.class_thresholds.end()) {
      tr.class_thresholds.emplace_back(p.class_id, l.th);
    } else {
      it->second = l.th;
    }
  }
  for (auto& [m, tr] : trends) {
    tr.window_s = window_h;
    tr.time_axis_label = "hours since " + lines.front().t_utc;
    data.trends.push_back(std::move(tr));
  }
  const double hours = (t_last - t_first) / 3600.0;
  data.title = "PTDA event history" + (joint.empty() ? std::string() : " of " + joint);
  RecordingSummary rs;
  rs.label = "history";
  rs.duration_s = hours + window_h;
  rs.alarm = first_alarm.has_value();
  rs.verdict = first_alarm ? "ALARM first at " + *first_alarm + " (" + std::to_string(alarm_windows) +
                                 " windows with the alarm active)"
                           : "no alarm in " + std::to_string(judged) + " judged windows";
  data.recordings.push_back(rs);
  data.summary = {{"history", dir.string() + " (" + std::to_string(files.size()) + " file(s))"},
                  {"from", lines.front().t_utc},
                  {"to", lines.back().t_utc},
                  {"span", fixed(hours, 2) + " h"},
                  {"windows", std::to_string(windows)},
                  {"judged", std::to_string(judged)},
                  {"abnormal", std::to_string(abnormal)},
                  {"alarm active", std::to_string(alarm_windows) + " windows"},
                  {"state changes", std::to_string(state_notes.size())}};
  if (!joint.empty()) data.summary.insert(data.summary.begin(), {"joint", joint});
  // The latest state changes (the whole list can be long on a flapping cell).
  constexpr std::size_t kStateNotes = 50;
  if (state_notes.size() > kStateNotes) {
    notes.push_back(std::to_string(state_notes.size() - kStateNotes) + " earlier state changes not listed");
    state_notes.erase(state_notes.begin(), state_notes.end() - static_cast<std::ptrdiff_t>(kStateNotes));
  }
  for (auto& s : state_notes) notes.push_back(std::move(s));
  data.notes = std::move(notes);
  return data;
}

}  // namespace ptda::cli
