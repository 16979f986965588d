// Recording view, CAN-based segmentation and window cutting for the gap diagnosis.
#include "ptda/gap/signals.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/dsp/real_fft.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"

namespace ptda::gap {
namespace {

constexpr double kMarginS = 0.02;  // kept clear of segment ends (CAN delay, jitter, blend edges)
constexpr double kMaxConstWindowS = 0.5;
constexpr double kMaxOtherWindowS = 0.25;
constexpr std::size_t kMinWindow = 256;
constexpr std::size_t kMaxWindowsPerSegment = 4;

std::size_t fft_len_at_most(double samples) {
  if (samples < static_cast<double>(kMinWindow)) return 0;
  auto n = static_cast<std::size_t>(samples);
  n -= n % 2;
  for (; n >= kMinWindow; n -= 2) {
    if (dsp::RealFft::supported_length(n)) return n;
  }
  return 0;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1));
  return v[i];
}

}  // namespace

const char* segment_type_name(SegmentType t) noexcept {
  switch (t) {
    case SegmentType::kConstant:
      return "constant";
    case SegmentType::kAccel:
      return "acceleration";
    case SegmentType::kStandstill:
      return "standstill";
  }
  return "?";
}

GapRecording load_recording(const std::filesystem::path& dir, const config::SpeedFrameSpec& frame,
                            double can_delay_s) {
  const formats::RecordingMeta meta = formats::read_recording_meta(dir);
  GapRecording rec;
  rec.source = dir.string();
  formats::WavInfo info;
  rec.accel_ms2 = formats::read_wav_channel(dir / meta.vibration_file, meta.channel, &info);
  rec.fs_hz = info.sample_rate_hz;
  for (float& v : rec.accel_ms2) v = static_cast<float>(v * meta.scale);
  const std::vector<formats::CandumpRecord> log = formats::read_candump(dir / meta.can_file);
  const std::int64_t t0_ns = seconds_to_ns(meta.start_time_s);
  for (const formats::CandumpRecord& r : log) {
    config::DecodedSpeed d;
    if (config::decode_speed(r.frame, frame, d) != config::DecodeResult::kOk) continue;
    rec.speed.push_back({ns_to_seconds(r.frame.t_ns - t0_ns) - can_delay_s, d.speed_rad_s});
  }
  if (rec.speed.size() < 2) {
    throw Error((dir / meta.can_file).string() + ": fewer than 2 speed frames with id " +
                std::to_string(frame.id) + " (check the scenario's [can.speed_frame])");
  }
  return rec;
}

GapRecording recording_from_simulation(const sim::SimulatedSignals& sig, const sim::Scenario& s) {
  GapRecording rec;
  rec.source = "simulation";
  rec.fs_hz = sig.fs_nominal_hz;
  const double scale = sim::sensor_scale(s.sensor);
  rec.accel_ms2.resize(sig.codes.size());
  for (std::size_t i = 0; i < sig.codes.size(); ++i)
    rec.accel_ms2[i] = static_cast<float>(sig.codes[i] * scale);
  config::SpeedFrameSpec spec = s.can.speed_frame;
  const std::int64_t t0_ns = seconds_to_ns(s.start_time_s);
  for (const sim::SimCanFrame& f : sig.can) {
    if (!f.is_speed) continue;
    config::DecodedSpeed d;
    if (config::decode_speed(f.frame, spec, d) != config::DecodeResult::kOk) continue;
    rec.speed.push_back({ns_to_seconds(f.frame.t_ns - t0_ns) - s.can.delay_s, d.speed_rad_s});
  }
  return rec;
}

std::vector<Segment> segment_recording(const GapRecording& rec, double block_s) {
  std::vector<Segment> out;
  const std::vector<SpeedPoint>& sp = rec.speed;
  if (sp.size() < 3) return out;
  const double duration_s = static_cast<double>(rec.accel_ms2.size()) / rec.fs_hz;
  double w_max = 0.0;
  for (const SpeedPoint& p : sp) w_max = std::max(w_max, std::fabs(p.speed_rad_s));
  if (w_max <= 0.0) return out;
  const double still = 0.02 * w_max;
  const double accel_thr = 0.02 * w_max;  // rad/s per s
  auto classify = [&](std::size_t i) {
    if (std::fabs(sp[i].speed_rad_s) < still) return SegmentType::kStandstill;
    const std::size_t a = i == 0 ? 0 : i - 1;
    const std::size_t b = std::min(i + 1, sp.size() - 1);
    const double dt = sp[b].t_s - sp[a].t_s;
    const double acc = dt > 0.0 ? (sp[b].speed_rad_s - sp[a].speed_rad_s) / dt : 0.0;
    return std::fabs(acc) < accel_thr ? SegmentType::kConstant : SegmentType::kAccel;
  };
  // Runs of one type; constant runs also break when the speed moves by more than 1 %.
  std::size_t start = 0;
  SegmentType type = classify(0);
  auto flush = [&](std::size_t end) {  // points [start, end)
    Segment s;
    s.type = type;
    s.t0_s = std::max(0.0, start == 0 ? 0.0 : 0.5 * (sp[start - 1].t_s + sp[start].t_s));
    s.t1_s = std::min(duration_s, end >= sp.size() ? duration_s : 0.5 * (sp[end - 1].t_s + sp[end].t_s));
    double sum = 0.0;
    for (std::size_t i = start; i < end; ++i) sum += sp[i].speed_rad_s;
    s.speed_rad_s = sum / static_cast<double>(end - start);
    if (s.t1_s > s.t0_s) out.push_back(s);
  };
  for (std::size_t i = 1; i < sp.size(); ++i) {
    const SegmentType t = classify(i);
    const bool speed_jump = t == SegmentType::kConstant && type == SegmentType::kConstant &&
                            std::fabs(sp[i].speed_rad_s - sp[start].speed_rad_s) > 0.01 * w_max;
    if (t != type || speed_jump) {
      flush(i);
      start = i;
      type = t;
    }
  }
  flush(sp.size());

  bool has_still = false;
  for (const Segment& s : out) has_still = has_still || s.type == SegmentType::kStandstill;
  if (!has_still) {
    // Test rig: constant speed throughout. Blocks play the role of job cycles.
    std::vector<Segment> blocks;
    std::uint32_t c = 0;
    for (const Segment& s : out) {
      if (s.type != SegmentType::kConstant) {
        blocks.push_back(s);
        continue;
      }
      for (double t = s.t0_s; t + block_s <= s.t1_s + 1e-9; t += block_s) {
        Segment b = s;
        b.t0_s = t;
        b.t1_s = t + block_s;
        b.cycle = c++;
        blocks.push_back(b);
      }
    }
    return blocks;
  }
  std::uint32_t cycle = 0;
  bool started = false;
  for (std::size_t i = 0; i < out.size(); ++i) {
    // A cycle starts after a real rest (a reversal passes through zero speed only briefly).
    if (i > 0 && out[i].type != SegmentType::kStandstill && out[i - 1].type == SegmentType::kStandstill &&
        out[i - 1].t1_s - out[i - 1].t0_s >= 0.1) {
      if (started) ++cycle;
      started = true;
    }
    if (out[i].type != SegmentType::kStandstill) started = true;
    out[i].cycle = cycle;
  }
  return out;
}

AnalysisPlan make_plan(const GapRecording& rec, const std::vector<Segment>& segs) {
  AnalysisPlan plan;
  plan.fs_hz = rec.fs_hz;
  bool block_mode = true;
  for (const Segment& s : segs) block_mode = block_mode && s.type == SegmentType::kConstant;
  const double margin = block_mode ? 0.0 : kMarginS;
  std::vector<std::vector<double>> class_durs;
  std::vector<double> accel_durs;
  std::vector<double> still_durs;
  for (const Segment& s : segs) {
    plan.cycles = std::max(plan.cycles, s.cycle + 1);
    const double dur = s.t1_s - s.t0_s;
    if (s.type == SegmentType::kAccel) {
      if (dur >= 0.05) accel_durs.push_back(dur);
      continue;
    }
    if (s.type == SegmentType::kStandstill) {
      if (dur >= 0.1) still_durs.push_back(dur - 2 * margin);
      continue;
    }
    if (dur < 0.06) continue;
    std::size_t c = 0;
    for (; c < plan.speeds.size(); ++c) {
      if (std::fabs(plan.speeds[c] - s.speed_rad_s) <= 0.02 * std::fabs(plan.speeds[c])) break;
    }
    if (c == plan.speeds.size()) {
      plan.speeds.push_back(s.speed_rad_s);
      class_durs.emplace_back();
    }
    class_durs[c].push_back(dur - 2 * margin);
  }
  for (std::size_t c = 0; c < plan.speeds.size(); ++c) {
    const double d = std::min(kMaxConstWindowS, quantile(class_durs[c], 0.25));
    plan.const_len.push_back(fft_len_at_most(d * rec.fs_hz));
  }
  if (!accel_durs.empty())
    plan.accel_len = fft_len_at_most(std::min(kMaxOtherWindowS, quantile(accel_durs, 0.25)) * rec.fs_hz);
  if (!still_durs.empty())
    plan.still_len = fft_len_at_most(std::min(kMaxOtherWindowS, quantile(still_durs, 0.25)) * rec.fs_hz);
  return plan;
}

std::vector<Window> cut_windows(const GapRecording& rec, const std::vector<Segment>& segs,
                                const AnalysisPlan& plan) {
  std::vector<Window> out;
  bool block_mode = true;
  for (const Segment& s : segs) block_mode = block_mode && s.type == SegmentType::kConstant;
  const double margin = block_mode ? 0.0 : kMarginS;
  const double fs = rec.fs_hz;
  const std::size_t n_total = rec.accel_ms2.size();
  for (const Segment& s : segs) {
    Window w;
    w.type = s.type;
    w.cycle = s.cycle;
    w.speed_rad_s = s.speed_rad_s;
    if (s.type == SegmentType::kConstant) {
      int cls = -1;
      for (std::size_t c = 0; c < plan.speeds.size(); ++c) {
        if (std::fabs(plan.speeds[c] - s.speed_rad_s) <= 0.02 * std::fabs(plan.speeds[c]))
          cls = static_cast<int>(c);
      }
      if (cls < 0 || plan.const_len[static_cast<std::size_t>(cls)] == 0) continue;
      w.speed_class = cls;
      w.len = plan.const_len[static_cast<std::size_t>(cls)];
      const double avail = (s.t1_s - s.t0_s - 2 * margin) * fs;
      const auto k = std::min(kMaxWindowsPerSegment,
                              static_cast<std::size_t>(std::max(0.0, avail) / static_cast<double>(w.len)));
      const auto first = static_cast<std::size_t>(std::ceil((s.t0_s + margin) * fs));
      for (std::size_t j = 0; j < k; ++j) {
        w.start = first + j * w.len;
        if (w.start + w.len <= n_total) out.push_back(w);
      }
      continue;
    }
    w.len = s.type == SegmentType::kAccel ? plan.accel_len : plan.still_len;
    if (w.len == 0) continue;
    const double m = s.type == SegmentType::kAccel ? 0.0 : margin;
    const double avail = (s.t1_s - s.t0_s - 2 * m) * fs;
    if (avail < static_cast<double>(w.len)) continue;
    const double centre = 0.5 * (s.t0_s + s.t1_s) * fs;
    const double st = centre - 0.5 * static_cast<double>(w.len);
    if (st < 0.0) continue;
    w.start = static_cast<std::size_t>(st);
    if (w.start + w.len <= n_total) out.push_back(w);
  }
  return out;
}

ProgramSplit find_program_split(const std::vector<Segment>& segs, const AnalysisPlan& plan,
                                double duration_s) {
  ProgramSplit out;
  out.units = plan.cycles;
  const std::uint32_t n = out.units;
  // Signatures: constant classes in order; a move without a plateau by its direction.
  std::vector<std::vector<int>> sig(n);
  std::vector<double> start_s(n, -1.0), motion_sum(n, 0.0);
  for (const Segment& s : segs) {
    if (s.cycle >= n) continue;
    if (start_s[s.cycle] < 0.0 && s.type != SegmentType::kStandstill) start_s[s.cycle] = s.t0_s;
    motion_sum[s.cycle] += s.speed_rad_s * (s.t1_s - s.t0_s);
    if (s.type != SegmentType::kConstant || s.t1_s - s.t0_s < 0.06) continue;
    for (std::size_t c = 0; c < plan.speeds.size(); ++c) {
      if (std::fabs(plan.speeds[c] - s.speed_rad_s) <= 0.02 * std::fabs(plan.speeds[c])) {
        if (sig[s.cycle].empty() || sig[s.cycle].back() != static_cast<int>(c))
          sig[s.cycle].push_back(static_cast<int>(c));
        break;
      }
    }
  }
  for (std::uint32_t u = 0; u < n; ++u) {
    if (sig[u].empty()) sig[u].push_back(motion_sum[u] >= 0.0 ? -1 : -2);
    if (start_s[u] < 0.0) {  // a unit of standstill only: after the previous one
      start_s[u] = u > 0 ? start_s[u - 1] : 0.0;
    }
  }
  out.period_units = 1;
  for (std::uint32_t p = 1; 2 * p <= n; ++p) {
    std::uint32_t same = 0;
    for (std::uint32_t u = 0; u + p < n; ++u) same += sig[u] == sig[u + p] ? 1U : 0U;
    if (static_cast<double>(same) >= 0.75 * static_cast<double>(n - p)) {
      out.period_units = p;
      break;
    }
  }
  const std::uint32_t p = out.period_units;
  out.periods = n / p;
  if (n > p) {
    out.period_s = (start_s[n - 1] - start_s[(n - 1) % p]) / static_cast<double>((n - 1) / p);
  } else {
    out.period_s = duration_s;
  }
  out.fit.assign(n, 0);
  out.held.assign(n, 0);
  for (std::uint32_t u = 0; u < n; ++u) (((u / p) + (u % p)) % 2 == 0 ? out.fit : out.held)[u] = 1;
  out.enough = out.periods >= 2 && n >= 4;
  if (!out.enough) {
    const std::uint32_t need_periods = std::max<std::uint32_t>(2, (4 + p - 1) / p);
    char b[400];
    std::snprintf(b, sizeof b,
                  "too short to split: %u move(s)/block(s), the program repeats every %u of them (%.2f s); "
                  "a fit and a held-out part that both hold every segment class need >= %u periods and "
                  ">= 4 moves, about %.1f s of recording (this one is %.1f s)",
                  n, p, out.period_s, need_periods,
                  (n > 0 ? start_s[0] : 0.0) + static_cast<double>(need_periods) * out.period_s + 0.5,
                  duration_s);
    out.need = b;
  }
  return out;
}

std::vector<std::string> missing_classes(const std::vector<Window>& windows, const AnalysisPlan& plan,
                                         const std::vector<char>& fit, const std::vector<char>& held) {
  // Index: constant classes 0..n-1, then acceleration, then standstill.
  const std::size_t nc = plan.speeds.size();
  std::vector<int> in_fit(nc + 2, 0), in_held(nc + 2, 0);
  for (const Window& w : windows) {
    const std::size_t i = w.type == SegmentType::kConstant ? static_cast<std::size_t>(w.speed_class)
                          : w.type == SegmentType::kAccel  ? nc
                                                           : nc + 1;
    if (w.cycle < fit.size() && fit[w.cycle]) in_fit[i] = 1;
    if (w.cycle < held.size() && held[w.cycle]) in_held[i] = 1;
  }
  std::vector<std::string> out;
  for (std::size_t i = 0; i < nc + 2; ++i) {
    if (in_fit[i] == in_held[i]) continue;
    std::string name;
    if (i < nc) {
      char b[96];
      std::snprintf(b, sizeof b, "constant class %zu (%+.3f rad/s)", i, plan.speeds[i]);
      name = b;
    } else {
      name = i == nc ? "acceleration" : "standstill";
    }
    out.push_back(name + (in_fit[i] ? " not in the held-out part" : " not in the fit part"));
  }
  return out;
}

LinePresence line_presence(const GapRecording& rec, const std::vector<Segment>& segs,
                           const std::vector<char>& use_cycle, double f_hz, double gmf_per_rad_s) {
  LinePresence out;
  const double fs = rec.fs_hz;
  const auto n = static_cast<std::size_t>(std::max(64.0, std::round(0.1 * fs)));
  const double df = fs / static_cast<double>(n);
  if (!(f_hz > 9.0 * df) || f_hz > 0.5 * fs - 9.0 * df || rec.accel_ms2.size() < n) return out;
  std::vector<double> hann(n);
  for (std::size_t i = 0; i < n; ++i)
    hann[i] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n));
  // The line's bin and 12 floor bins (+-3..8 bins), each evaluated by a rotating phasor.
  std::vector<double> freqs{f_hz};
  for (int m = 3; m <= 8; ++m) {
    freqs.push_back(f_hz - m * df);
    freqs.push_back(f_hz + m * df);
  }
  std::vector<double> ratios;
  std::vector<double> floor_p(freqs.size() - 1);
  for (const Segment& sg : segs) {
    if (sg.type == SegmentType::kAccel) continue;
    if (!use_cycle.empty() && (sg.cycle >= use_cycle.size() || !use_cycle[sg.cycle])) continue;
    if (sg.type == SegmentType::kConstant && gmf_per_rad_s > 0.0) {
      const double gmf = gmf_per_rad_s * std::fabs(sg.speed_rad_s);
      const double k = std::round(f_hz / std::max(gmf, 1e-9));
      if (gmf > 0.0 && k >= 1.0 && std::fabs(f_hz - k * gmf) < 4.0 * df) continue;
    }
    const auto i_end = std::min(rec.accel_ms2.size(), static_cast<std::size_t>(std::floor(sg.t1_s * fs)));
    for (auto i0 = static_cast<std::size_t>(std::ceil(std::max(0.0, sg.t0_s) * fs)); i0 + n <= i_end;
         i0 += n) {
      double line = 0.0;
      for (std::size_t j = 0; j < freqs.size(); ++j) {
        const double w = 2.0 * std::numbers::pi * freqs[j] / fs;
        const double cw = std::cos(w), sw = std::sin(w);
        double c = 1.0, s = 0.0, re = 0.0, im = 0.0;
        for (std::size_t i = 0; i < n; ++i) {
          const double v = hann[i] * static_cast<double>(rec.accel_ms2[i0 + i]);
          re += v * c;
          im -= v * s;
          const double c2 = c * cw - s * sw;
          s = s * cw + c * sw;
          c = c2;
        }
        const double p = re * re + im * im;
        if (j == 0) {
          line = p;
        } else {
          floor_p[j - 1] = p;
        }
      }
      std::nth_element(floor_p.begin(), floor_p.begin() + static_cast<std::ptrdiff_t>(floor_p.size() / 2),
                       floor_p.end());
      const double fl = floor_p[floor_p.size() / 2];
      ratios.push_back(fl > 0.0 ? line / fl : 1.0);
    }
  }
  out.frames = static_cast<std::uint32_t>(ratios.size());
  if (ratios.size() < 8) return out;
  std::sort(ratios.begin(), ratios.end());
  const std::size_t top0 = ratios.size() - std::max<std::size_t>(1, ratios.size() / 10);
  const std::vector<double> top(ratios.begin() + static_cast<std::ptrdiff_t>(top0), ratios.end());
  const double on = top[top.size() / 2];
  out.on_level_db = 10.0 * std::log10(std::max(on, 1e-12));
  if (on < 10.0) return out;
  const double thr = std::sqrt(on);
  const auto n_on = static_cast<double>(ratios.end() - std::upper_bound(ratios.begin(), ratios.end(), thr));
  out.share = n_on / static_cast<double>(ratios.size());
  out.judged = true;
  return out;
}

}  // namespace ptda::gap
