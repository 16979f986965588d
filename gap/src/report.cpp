// JSON (schema "ptda-gap" v1) and HTML output of a diagnosis (docs/gap.md "Output").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

#include "ptda/gap/diagnose.hpp"

namespace ptda::gap {
namespace {

std::string esc(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '"':
        o += "\\\"";
        break;
      case '\\':
        o += "\\\\";
        break;
      case '\n':
        o += "\\n";
        break;
      case '<':
        o += "\\u003c";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char b[8];
          std::snprintf(b, sizeof b, "\\u%04x", c);
          o += b;
        } else {
          o += c;
        }
    }
  }
  return "\"" + o + "\"";
}

std::string num(double v) {
  if (!std::isfinite(v)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

std::string map_json(const std::map<std::string, double>& m, double total) {
  std::string s = "{";
  bool first = true;
  for (const auto& [k, v] : m) {
    s += (first ? "" : ", ") + esc(k) + ": {\"gap\": " + num(v) +
         ", \"share\": " + num(total > 0 ? v / total : 0.0) + "}";
    first = false;
  }
  return s + "}";
}

std::string breakdown_json(const GapBreakdown& g, const std::string& ind) {
  std::ostringstream o;
  o << "{\n" << ind << "  \"total\": " << num(g.total) << ",\n";
  o << ind << "  \"by_probe\": " << map_json(g.by_probe, g.total) << ",\n";
  o << ind << "  \"by_band\": " << map_json(g.by_band, g.total) << ",\n";
  o << ind << "  \"by_segment\": " << map_json(g.by_segment, g.total) << ",\n";
  o << ind << "  \"by_stage\": " << map_json(g.by_stage, g.total) << ",\n";
  o << ind << "  \"noise_offset_db\": " << num(g.noise_offset_db) << ",\n";
  o << ind << "  \"top\": [";
  for (std::size_t i = 0; i < g.top.size(); ++i) {
    const auto& t = g.top[i];
    o << (i ? ",\n" : "\n") << ind << "    {\"probe\": " << esc(t.probe) << ", \"key\": " << esc(t.key)
      << ", \"real\": " << num(t.real) << ", \"sim\": " << num(t.sim) << ", \"z\": " << num(t.z)
      << ", \"contribution\": " << num(t.contribution) << "}";
  }
  o << "\n" << ind << "  ]\n" << ind << "}";
  return o.str();
}

std::string effect_json(const sim::EffectSpec& e) {
  const sim::EffectInfo& info = sim::effect_info(e.kind);
  std::string s = "{\"kind\": " + esc(info.name) + ", \"params\": {";
  for (std::size_t i = 0; i < info.params.size() && i < e.params.size(); ++i) {
    s += (i ? ", " : "") + esc(info.params[i].name) + ": " + num(e.params[i]);
  }
  return s + "}}";
}

std::string candidate_json(const CandidateResult& c) {
  std::string alternatives;
  if (!c.alternatives.empty()) {
    alternatives = ", \"alternatives\": [";
    for (std::size_t i = 0; i < c.alternatives.size(); ++i)
      alternatives += (i ? ", " : "") + esc(c.alternatives[i]);
    alternatives += "]";
  }
  return "{\"effect\": " + effect_json(c.effect) + ", \"location\": " + esc(c.location) +
         ", \"fully_fitted\": " + (c.fully_fitted ? "true" : "false") + ", \"gap_fit\": " + num(c.gap_fit) +
         ", \"gap_heldout\": " + num(c.gap_heldout) +
         ", \"gap_heldout_replicate\": " + num(c.gap_heldout_replicate) +
         ", \"shrink_pct\": " + num(c.shrink_pct) + ", \"evaluations\": " + std::to_string(c.evaluations) +
         (c.accepted_locally ? ", \"accepted_locally\": true" : "") + alternatives + "}";
}

std::string array_json(const std::vector<double>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + num(v[i]);
  return s + "]";
}

std::string strings_json(const std::vector<std::string>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + esc(v[i]);
  return s + "]";
}

// ---- HTML ----------------------------------------------------------------------------------------

std::string svg_bars(const std::vector<std::pair<std::string, double>>& bars, const std::string& title) {
  const int w = 640, row = 18, left = 220;
  const int h = 30 + row * static_cast<int>(bars.size());
  double mx = 1e-12;
  for (const auto& b : bars) mx = std::max(mx, b.second);
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << w << "' height='" << h << "'>";
  o << "<text x='4' y='14' font-size='13' font-weight='bold'>" << title << "</text>";
  for (std::size_t i = 0; i < bars.size(); ++i) {
    const int y = 22 + row * static_cast<int>(i);
    const double bw = (w - left - 60) * bars[i].second / mx;
    o << "<text x='4' y='" << y + 12 << "' font-size='11'>" << bars[i].first << "</text>";
    o << "<rect x='" << left << "' y='" << y + 2 << "' width='" << bw << "' height='" << row - 5
      << "' fill='#4a7ab5'/>";
    o << "<text x='" << left + bw + 4 << "' y='" << y + 12 << "' font-size='11'>" << num(bars[i].second)
      << "</text>";
  }
  o << "</svg>";
  return o.str();
}

std::string svg_spectra(const Diagnosis& d) {
  if (d.spectrum_real_db.empty()) return "<p>(no constant-speed spectrum)</p>";
  const int w = 900, h = 320, l = 50, b = 30;
  const std::size_t n = d.spectrum_real_db.size();
  double lo = 1e300, hi = -1e300;
  for (double v : d.spectrum_real_db) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  lo = std::max(lo, hi - 100.0);
  auto path = [&](const std::vector<double>& v, const char* colour) {
    std::ostringstream o;
    o << "<polyline fill='none' stroke='" << colour << "' stroke-width='0.8' points='";
    for (std::size_t k = 0; k < v.size() && k < n; ++k) {
      const double x = l + (w - l - 10) * static_cast<double>(k) / static_cast<double>(n - 1);
      const double y = 10 + (h - b - 10) * (hi - std::clamp(v[k], lo, hi)) / (hi - lo);
      o << x << "," << y << " ";
    }
    o << "'/>";
    return o.str();
  };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << w << "' height='" << h << "'>";
  o << path(d.spectrum_nominal_db, "#bbbbbb") << path(d.spectrum_final_db, "#d9822b")
    << path(d.spectrum_real_db, "#1f4e8c");
  o << "<text x='" << l << "' y='" << h - 8 << "' font-size='11'>0 Hz</text><text x='" << w - 90 << "' y='"
    << h - 8 << "' font-size='11'>" << num(d.spectrum_df_hz * static_cast<double>(n - 1)) << " Hz</text>";
  o << "<text x='4' y='20' font-size='11'>" << num(hi) << " dB</text><text x='4' y='" << h - b
    << "' font-size='11'>" << num(lo) << " dB</text>";
  o << "<text x='" << l + 10 << "' y='24' font-size='11' fill='#1f4e8c'>measured (held-out)</text>";
  o << "<text x='" << l + 150 << "' y='24' font-size='11' fill='#999'>calibrated nominal</text>";
  o << "<text x='" << l + 290 << "' y='24' font-size='11' fill='#d9822b'>with chosen effects</text>";
  o << "</svg>";
  return o.str();
}

std::string html_esc(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<')
      o += "&lt;";
    else if (c == '>')
      o += "&gt;";
    else if (c == '&')
      o += "&amp;";
    else
      o += c;
  }
  return o;
}

std::vector<std::pair<std::string, double>> sorted(const std::map<std::string, double>& m) {
  std::vector<std::pair<std::string, double>> v(m.begin(), m.end());
  std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
  return v;
}

}  // namespace

std::string diagnosis_json(const Diagnosis& d) {
  std::ostringstream o;
  o << "{\n  \"format\": \"ptda-gap\",\n  \"version\": 1,\n";
  o << "  \"scenario\": " << esc(d.scenario) << ",\n  \"real\": " << esc(d.real_source) << ",\n";
  o << "  \"fs_hz\": " << num(d.fs_hz) << ",\n";
  o << "  \"split\": {\"cycles\": " << d.cycles << ", \"fit_cycles\": " << d.fit_cycles
    << ", \"heldout_cycles\": " << d.heldout_cycles << ", \"windows_fit\": " << d.windows_fit
    << ", \"windows_heldout\": " << d.windows_heldout
    << ", \"class_speeds_rad_s\": " << array_json(d.class_speeds_rad_s)
    << ", \"period_units\": " << d.period_units << ", \"period_s\": " << num(d.period_s)
    << ", \"missing_classes\": " << strings_json(d.split_missing) << "},\n";
  o << "  \"motion\": {\"source\": " << esc(d.motion_source) << ", \"note\": " << esc(d.motion_note)
    << "},\n";
  o << "  \"not_identifiable\": " << strings_json(d.not_identifiable) << ",\n";
  o << "  \"calibration\": {\"gmf_amplitudes\": " << array_json(d.calibrated_gmf_amplitudes)
    << ", \"gmf_phases_rad\": " << array_json(d.calibrated_gmf_phases_rad)
    << ", \"noise_rms\": " << num(d.calibrated_noise_rms)
    << ", \"noise_tilt_db_per_decade\": " << num(d.calibrated_noise_tilt_db_per_decade)
    << ", \"recalibrated\": " << (d.recalibrated ? "true" : "false")
    << ", \"speed_scale\": {\"tolerance\": " << num(d.speed_scale_tolerance)
    << ", \"ppm\": " << num(d.speed_scale_ppm) << ", \"sd_ppm\": " << num(d.speed_scale_sd_ppm)
    << ", \"lines\": " << d.speed_scale_lines << ", \"applied_ppm\": " << num(d.speed_scale_applied_ppm)
    << ", \"slip_only\": " << (d.speed_scale_slip_only ? "true" : "false") << "}, \"params\": [";
  for (std::size_t i = 0; i < d.calibration.size(); ++i) {
    const CalibratedParam& c = d.calibration[i];
    o << (i ? "," : "") << "\n    {\"name\": " << esc(c.name) << ", \"order\": " << c.order
      << ", \"nominal\": " << num(c.nominal) << ", \"calibrated\": " << num(c.calibrated)
      << ", \"offset_db\": " << num(c.offset_db) << ", \"sd_db\": " << num(c.sd_db)
      << ", \"significant\": " << (c.significant ? "true" : "false") << ", \"sentence\": " << esc(c.sentence)
      << "}";
  }
  o << "]},\n";
  o << "  \"noise_gap\": " << num(d.noise_gap) << ",\n";
  o << "  \"noise_gap_sd\": " << num(d.noise_gap_sd) << ",\n";
  o << "  \"alarm_rate_heldout\": {\"nominal\": " << num(d.alarm_rate_nominal)
    << ", \"final\": " << num(d.alarm_rate_final) << "},\n";
  o << "  \"gap_heldout_replicate\": " << num(d.nominal_heldout_replicate) << ",\n";
  o << "  \"gap_significant\": " << (d.gap_significant ? "true" : "false") << ",\n";
  o << "  \"gap\": " << breakdown_json(d.nominal_heldout, "  ") << ",\n";
  o << "  \"rounds\": [";
  for (std::size_t r = 0; r < d.rounds.size(); ++r) {
    const SelectionRound& sr = d.rounds[r];
    o << (r ? "," : "") << "\n    {\"gap_before_heldout\": " << num(sr.gap_before_heldout)
      << ", \"gap_before_heldout_replicate\": " << num(sr.gap_before_heldout_replicate)
      << ", \"null_heldout\": " << num(sr.null_heldout)
      << ", \"null_heldout_replicate\": " << num(sr.null_heldout_replicate)
      << ", \"null_reference\": " << (sr.null_reference ? "true" : "false")
      << ", \"accepted\": " << sr.accepted << ", \"candidates\": [";
    for (std::size_t i = 0; i < sr.ranked.size(); ++i)
      o << (i ? ",\n      " : "\n      ") << candidate_json(sr.ranked[i]);
    o << "]}";
  }
  o << "\n  ],\n  \"chosen\": [";
  for (std::size_t i = 0; i < d.chosen.size(); ++i) o << (i ? ", " : "") << candidate_json(d.chosen[i]);
  o << "],\n";
  o << "  \"remaining\": " << breakdown_json(d.final_heldout, "  ") << ",\n";
  o << "  \"total_shrink_pct\": " << num(d.total_shrink_pct) << ",\n";
  o << "  \"verdict\": " << esc(d.verdict) << ",\n";
  o << "  \"simulations\": " << d.simulations << ",\n  \"runtime_s\": " << num(d.runtime_s) << "\n}\n";
  return o.str();
}

std::string diagnosis_html(const Diagnosis& d) {
  std::ostringstream o;
  o << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>ptda gap: " << html_esc(d.scenario)
    << "</"
       "title><style>body{font-family:sans-serif;max-width:960px;margin:auto}table{border-collapse:collapse}"
       "td,th{border:1px solid #ccc;padding:2px 6px;font-size:12px}</style></head><body>";
  o << "<h1>Sim-to-real gap</h1><p><b>" << html_esc(d.verdict) << "</b></p>";
  o << "<p>Scenario <code>" << html_esc(d.scenario) << "</code>, recording <code>" << html_esc(d.real_source)
    << "</code>; " << d.cycles << " moves/blocks, program period " << d.period_units << " ("
    << num(d.period_s) << " s): " << d.fit_cycles << " fit / " << d.heldout_cycles << " held out; "
    << html_esc(d.motion_note) << "; " << d.simulations << " simulations, " << num(d.runtime_s) << " s.</p>";
  for (const std::string& m : d.split_missing) o << "<p>Split: " << html_esc(m) << "</p>";
  o << "<p>Held-out gap of the calibrated nominal model: " << num(d.nominal_heldout.total)
    << " (expected from the measured cycles' own spread: " << num(d.noise_gap) << " &plusmn; "
    << num(d.noise_gap_sd) << "); after the chosen effects: " << num(d.final_heldout.total) << " (shrink "
    << num(d.total_shrink_pct) << " %).</p>";
  o << "<p>Alarm stage: a PTDA baseline trained on the model flags " << num(100.0 * d.alarm_rate_nominal)
    << " % of the held-out constant-speed windows (calibrated nominal), " << num(100.0 * d.alarm_rate_final)
    << " % with the chosen effects.</p>";
  o << "<h2>Calibration (the nominal's own parameters, fitted on the fit part)</h2>";
  o << "<p>"
    << (d.recalibrated ? "The nominal was re-calibrated: calibration is not an unmodelled effect."
                       : "No calibrated parameter differs from the nominal beyond its uncertainty.")
    << "</p><table><tr><th>parameter</th><th>nominal</th><th>calibrated</th><th>offset dB</th><th>&plusmn; "
       "dB</th><th>in words</th></tr>";
  for (const CalibratedParam& c : d.calibration) {
    o << "<tr><td>" << html_esc(c.name) << "</td><td>" << num(c.nominal) << "</td><td>" << num(c.calibrated)
      << "</td><td>" << (c.significant ? "<b>" : "") << num(c.offset_db) << (c.significant ? "</b>" : "")
      << "</td><td>" << num(c.sd_db) << "</td><td>" << html_esc(c.sentence) << "</td></tr>";
  }
  o << "</table>";
  o << "<h2>Spectra (first constant-speed class)</h2>" << svg_spectra(d);
  o << "<h2>Where the gap lies (calibrated nominal, held-out)</h2>";
  o << svg_bars(sorted(d.nominal_heldout.by_probe), "by probe") << "<br>";
  o << svg_bars(sorted(d.nominal_heldout.by_band), "by band") << "<br>";
  o << svg_bars(sorted(d.nominal_heldout.by_segment), "by segment type") << "<br>";
  o << svg_bars(sorted(d.nominal_heldout.by_stage), "by pipeline stage");
  for (std::size_t r = 0; r < d.rounds.size(); ++r) {
    o << "<h2>Round " << r + 1 << ": candidates (held-out gap before " << num(d.rounds[r].gap_before_heldout)
      << "; with no effect, re-calibrated as the candidates are: " << num(d.rounds[r].null_heldout)
      << (d.rounds[r].null_reference ? ", the reference for the gain" : "") << ")</h2>";
    std::vector<std::pair<std::string, double>> bars;
    o << "<table><tr><th>effect</th><th>where</th><th>fit gap</th><th>held-out "
         "gap</th><th>replicate</th><th>shrink "
         "%</th></tr>";
    for (const CandidateResult& c : d.rounds[r].ranked) {
      o << "<tr><td>" << html_esc(sim::describe(c.effect)) << "</td><td>" << html_esc(c.location)
        << "</td><td>" << num(c.gap_fit) << "</td><td>" << num(c.gap_heldout) << "</td><td>"
        << num(c.gap_heldout_replicate) << "</td><td>" << num(c.shrink_pct) << "</td></tr>";
      if (c.fully_fitted) bars.push_back({sim::effect_info(c.effect.kind).name, std::max(0.0, c.shrink_pct)});
    }
    o << "</table>" << svg_bars(bars, "held-out shrink %");
  }
  o << "<h2>What remains</h2>" << svg_bars(sorted(d.final_heldout.by_probe), "remaining gap by probe");
  o << "<table><tr><th>probe</th><th>element</th><th>measured</th><th>model</th><th>z</th></tr>";
  for (const auto& t : d.final_heldout.top) {
    o << "<tr><td>" << t.probe << "</td><td>" << html_esc(t.key) << "</td><td>" << num(t.real) << "</td><td>"
      << num(t.sim) << "</td><td>" << num(t.z) << "</td></tr>";
  }
  o << "</table></body></html>\n";
  return o.str();
}

}  // namespace ptda::gap
