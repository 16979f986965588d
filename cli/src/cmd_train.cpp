// ptda train --recording DIR [--recording DIR ...] --config FILE --out BASELINE [--windows FROM:TO]
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <ostream>
#include <span>
#include <string>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/doctor.hpp"
#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/mesh_modulation.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/training.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::cli {

namespace {

dsp::Method method_of(const config::PipelineConfig& cfg) {
  return cfg.method;
}

std::string band_text(const dsp::Band& b) {
  return "[" + general(b.lo, 5) + ", " + general(b.hi, 5) + "]";
}

std::string stats_text(const dsp::FeatureStats& s) {
  return "mean " + general(s.mean, 5) + " sd " + general(s.stddev, 3) + " (n " + std::to_string(s.n) + ")";
}

// The summary of a written baseline (both domains).
int print_trained(std::ostream& out, const std::string& out_path, const dsp::Baseline& baseline,
                  const config::PipelineConfig& cfg, double fs_hz, const std::vector<std::string>& dropped) {
  if (baseline.domain == dsp::Domain::kOrder) {
    out << "baseline " << out_path << " (order domain): " << baseline.classes.size()
        << " speed class(es), N = " << baseline.window_len << " angle samples (" << baseline.revolutions
        << " input-shaft revolutions of " << baseline.samples_per_rev << " samples)\n";
    if (!cfg.order.speed_law) {
      out << "  speed law: off ([extraction] speed_law = false)\n";
    } else if (baseline.speed_law_se == 0.0 && baseline.speed_law_fit == 0.0) {
      out << "  speed law: not fitted (too few windows or one speed per class)\n";
    } else {
      out << "  speed law: window RMS ~ |speed|^p, p = " << fixed(baseline.speed_law_fit, 3) << " +- "
          << fixed(baseline.speed_law_se, 3)
          << (baseline.speed_law_exponent != 0.0 ? " (applied: every window is scaled to its class's speed)\n"
                                                 : " (not significant, |p| <= 2 se: not applied)\n");
    }
  } else {
    out << "baseline " << out_path << ": " << baseline.classes.size()
        << " segment class(es), N = " << baseline.window_len << " samples ("
        << fixed(1000.0 * baseline.window_len / fs_hz, 1) << " ms) at " << general(fs_hz, 10) << " Hz\n";
  }
  out << "  threshold policy: " << config::threshold_kind_name(baseline.policy.kind) << ", false-alarm rate "
      << general(baseline.policy.false_alarm_rate) << " per window and feature, margin "
      << general(baseline.policy.margin);
  if (baseline.policy.kind == dsp::ThresholdPolicy::Kind::kTolerance)
    out << ", confidence " << general(baseline.policy.confidence) << " (rms_res on a log scale)";
  out << ", hold-out " << general(baseline.policy.holdout_fraction) << " of each class's latest cycles\n";
  if (baseline.policy.ptda_line_gain) {
    out << "  PTDA line gain: on (a gain per window on each line group of the healthy spectrum; groups per "
           "class:";
    for (const auto& c : baseline.classes) out << " " << c.line_groups.size();
    out << ")\n";
  }
  if (baseline.policy.ptda_floor_gain)
    out << "  PTDA floor gain: on (the floor outside the line groups gets the window's median gain; rms_res "
           "is referred to the training floor)\n";
  const dsp::SequentialConfig& seq = cfg.decision.sequential;
  out << "  decision: alarm when " << cfg.decision.k << " of the last " << cfg.decision.n
      << " windows are abnormal";
  if (seq.enabled) {
    out << " or a class's CUSUM reaches " << general(seq.h_alarm) << " (warning " << general(seq.h_warn)
        << ", k " << general(seq.k) << ")";
  }
  out << "\n";
  for (const auto& c : baseline.classes) {
    const auto& s = c.segment;
    out << "class " << s.id << ": direction " << (s.direction < 0 ? "-" : "+") << ", speed "
        << fixed(s.speed_rad_s, 4) << " +- " << fixed(s.speed_tol_rad_s, 4) << " rad/s, duration "
        << fixed(s.duration_s, 3) << " s, " << s.regions << " regions, " << c.n_windows << " windows\n";
    for (std::size_t m = 0; m < dsp::kMethodCount; ++m) {
      const auto method = static_cast<dsp::Method>(m);
      out << "  " << pad_right(std::string(dsp::method_name(method)), 4) << "  rms_res "
          << pad_right(band_text(c.thresholds[m].rms), 22) << " " << stats_text(c.rms_stats[m])
          << "\n        entropy " << pad_right(band_text(c.thresholds[m].entropy), 22) << " "
          << stats_text(c.entropy_stats[m]) << "\n";
      const dsp::DaySpread& d = c.day_spread[m];
      out << "        between days (" << d.recordings << " recording" << (d.recordings == 1 ? "" : "s")
          << "): ln(rms_res) sd within " << general(d.log_rms_within_sd, 3) << ", between "
          << general(d.log_rms_between_sd, 3)
          << (d.recordings > 1 ? " (estimate " + general(d.log_rms_between_est, 3) + " pooled with the prior)"
                               : std::string(" (prior: day_sd_floor x within)"))
          << "; entropy sd within " << general(d.entropy_within_sd, 3) << ", between "
          << general(d.entropy_between_sd, 3)
          << (d.recordings > 1 ? " (estimate " + general(d.entropy_between_est, 3) + " pooled with the prior)"
                               : std::string(" (prior: day_sd_floor x within)"))
          << "\n";
      const dsp::SeqScale zs = dsp::sequential_scale(c, method, baseline.policy, seq.day_allowance);
      const dsp::HoldoutStats& h = c.holdout[m];
      if (h.windows > 0) {
        const double frac = static_cast<double>(h.abnormal) / h.windows;
        out << "        hold-out: " << h.abnormal << " of " << h.windows << " healthy windows abnormal ("
            << general(100.0 * frac, 3) << " %, " << general(frac * c.windows_per_hour, 3) << " per hour at "
            << general(c.windows_per_hour, 4) << " windows/h; rms high " << h.rms_high << ", entropy "
            << h.entropy_out << "), low residual " << h.rms_low;
        if (h.abnormal == 0) out << "; rate <= " << general(3.0 / h.windows, 3) << " per window (95 %)";
        out << "\n";
        if (seq.enabled && h.windows >= 3 && h.z_rms_sd > 0.0 && h.z_entropy_sd > 0.0) {
          const double warn = dsp::class_cusum_arl(h.z_rms_mean, h.z_rms_sd, h.z_entropy_mean, h.z_entropy_sd,
                                                   seq.k, seq.h_warn, zs.rms_allowance, zs.entropy_allowance);
          const double alarm =
              dsp::class_cusum_arl(h.z_rms_mean, h.z_rms_sd, h.z_entropy_mean, h.z_entropy_sd, seq.k,
                                   seq.h_alarm, zs.rms_allowance, zs.entropy_allowance);
          const double per_day = 24.0 * c.windows_per_hour;
          out << "        CUSUM on the hold-out (z_rms mean " << general(h.z_rms_mean, 3) << " sd "
              << general(h.z_rms_sd, 3) << ", z_entropy mean " << general(h.z_entropy_mean, 3) << " sd "
              << general(h.z_entropy_sd, 3) << "): ARL " << general(warn, 3) << " / " << general(alarm, 3)
              << " windows, false warnings / alarms per day " << general(per_day / warn, 3) << " / "
              << general(per_day / alarm, 3) << "\n";
        }
      }
    }
    if (seq.enabled) {
      // Nominal: standardised healthy features ~ N(0, 1), no day offset.
      const dsp::SeqScale zs = dsp::sequential_scale(c, method_of(cfg), baseline.policy, seq.day_allowance);
      const double per_day = 24.0 * c.windows_per_hour;
      const double warn =
          dsp::class_cusum_arl(0.0, 1.0, 0.0, 1.0, seq.k, seq.h_warn, zs.rms_allowance, zs.entropy_allowance);
      const double alarm = dsp::class_cusum_arl(0.0, 1.0, 0.0, 1.0, seq.k, seq.h_alarm, zs.rms_allowance,
                                                zs.entropy_allowance);
      out << "  CUSUM (" << dsp::method_name(method_of(cfg)) << "): allowance k " << general(seq.k)
          << " + between days " << general(zs.rms_allowance, 3) << " (z_rms) / "
          << general(zs.entropy_allowance, 3) << " (z_entropy) = " << general(seq.day_allowance)
          << " between-day sd x sqrt(1 + 1/days) over the within-day sd\n";
      out << "  CUSUM nominal (z ~ N(0, 1)): ARL " << general(warn, 3) << " / " << general(alarm, 3)
          << " windows, false warnings / alarms per day " << general(per_day / warn, 3) << " / "
          << general(per_day / alarm, 3) << " at " << general(per_day, 4) << " windows/day\n";
    }
    if (!c.band_stats.empty()) {
      // The band CUSUM's statistics ([decision] band_cusum, docs/method.md §6 "Band detector").
      std::size_t used = 0;
      std::uint32_t clean = 0;
      double between = 0.0;
      for (const dsp::BandEnergyStats& b : c.band_stats) {
        used += b.clean_bins > 0 ? 1 : 0;
        clean += b.clean_bins;
        between = std::max(between, b.within_sd > 0.0 ? b.between_sd / b.within_sd : 0.0);
      }
      out << "  band CUSUM: " << used << " of " << c.band_stats.size() << " bands with clean floor bins ("
          << clean << " bins), " << c.band_recordings << " training recording(s), largest between-day / "
          << "within-day sd " << general(between, 3) << "\n";
    }
    if (!c.mesh_stats.empty()) {
      // The mesh CUSUM's statistics ([decision] mesh_cusum, docs/method.md §6 "Mesh detector").
      const double f_in = dsp::input_shaft_hz(baseline.gearbox.ratio, c.segment.speed_rad_s);
      const double revs = f_in * static_cast<double>(baseline.window_len) / baseline.fs_hz;
      out << "  mesh CUSUM: input shaft " << general(f_in, 4) << " Hz, " << general(revs, 3)
          << " revolutions per window";
      if (c.mesh_stats[0].windows == 0 && c.mesh_stats[1].windows == 0) {
        out << ": no mesh detector for this class ("
            << (revs < dsp::kMeshMinRevolutions
                    ? "fewer than 2 revolutions per window: a longer window_len or a faster segment would "
                      "have them"
                    : "fewer than 5 training windows with mesh features: no mesh harmonic is a line of the "
                      "class "
                      "mean, or the windows' speeds are outside the class, or the features did not vary")
            << ")\n";
      } else {
        for (std::size_t f = 0; f < c.mesh_stats.size(); ++f) {
          const dsp::MeshFeatureStats& m = c.mesh_stats[f];
          out << "; " << dsp::mesh_feature_name(f) << " " << general(m.mean, 3) << " +- "
              << general(std::sqrt(m.within_sd * m.within_sd + m.between_sd * m.between_sd), 3) << " ("
              << m.windows << " windows)";
        }
        out << ", " << c.mesh_recordings << " training recording(s)\n";
      }
    }
  }
  // Said once, where the configuration is decided (ptda monitor stays quiet about it).
  if (!cfg.mesh_off_reason.empty()) out << "note: mesh detector off: " << cfg.mesh_off_reason << "\n";
  for (const std::string& w : dsp::training_warnings(baseline)) out << "warning: " << w << "\n";
  for (const std::string& d : dropped) out << "warning: no class for " << d << ": dropped, never judged\n";
  return kExitOk;
}

/// One recording's windows in the baseline: `begin`..`end` index the training's window list.
struct TrainingSpan {
  dsp::TrainingRecording rec;
  std::size_t begin = 0, end = 0;
};

/// What each recording contributed to windows [first, last) of `refs` (--windows applied): its window
/// count and time range, for `ptda monitor`'s in-sample warning. Recordings with no window kept are left
/// out. Reads the spilled refs once, in order. Main thread; allocates.
template <class Ref>
std::vector<dsp::TrainingRecording> training_recordings(std::vector<TrainingSpan>& spans,
                                                        const dsp::SpillVector<Ref>& all_refs,
                                                        std::size_t first, std::size_t last) {
  std::vector<dsp::TrainingRecording> training;
  typename dsp::SpillVector<Ref>::Reader refs(all_refs);
  std::size_t i = 0;
  for (TrainingSpan& sp : spans) {
    const std::size_t b = std::max(sp.begin, first);
    const std::size_t e = std::min(sp.end, last);
    if (b >= e) continue;
    while (i < b) {
      (void)refs.next();
      ++i;
    }
    bool any = false;
    for (; i < e; ++i) {
      const Ref r = refs.next();
      const double from = ns_to_seconds(r.t_start_ns);
      const double to = ns_to_seconds(r.t_end_ns);
      sp.rec.from_unix_s = any ? std::min(sp.rec.from_unix_s, from) : from;
      sp.rec.to_unix_s = any ? std::max(sp.rec.to_unix_s, to) : to;
      any = true;
    }
    sp.rec.windows = static_cast<std::uint32_t>(e - b);
    training.push_back(sp.rec);
  }
  return training;
}

/// All training recordings share one sample rate: the first one's (kept in fs_hz / first_recording).
void take_rate(const RecordingInfo& rec, double fs, const std::string& dir, double& fs_hz,
               std::string& first_recording) {
  if (fs_hz == 0.0) {
    fs_hz = fs;
    first_recording = dir;
  } else if (fs != fs_hz) {
    throw Error(rec.wav_path.string() + ": sampled at " + general(fs, 10) + " Hz but " + first_recording +
                " at " + general(fs_hz, 10) + " Hz (all training recordings need one rate)");
  }
}

// `ptda train` in the order domain (docs/method.md §9): every recording through the angle resampler and
// the order window cutter three times (an index of the windows, then the class sums, then the
// leave-one-out features), train_order_baseline_streamed (speed-band classes, the time domain's
// per-class training and thresholds); no window is held.
int train_order(const ParsedArgs& a, const config::PipelineConfig& cfg, const std::string& config_path,
                const FractionRange& range, std::ostream& out) {
  // The index (each window's place, recording and mean square) spills beyond 32 KiB per list; the
  // windows come in two more passes over each recording, so memory does not grow with their length.
  dsp::OrderTrainingIndex all;
  std::string source = "ptda train";
  double fs_hz = 0.0;
  std::string first_recording;
  std::vector<TrainingSpan> spans;
  std::vector<RecordingInfo> recs;
  double recorded_s = 0.0;
  std::uint64_t seq_offset = 0, segment_offset = 0;  // renumbered as append_order_windows() does
  for (const auto& dir : a.values("recording")) {
    const RecordingInfo rec = open_recording(dir);
    const double fs = pipeline_fs_hz(rec, cfg, config_path);
    take_rate(rec, fs, dir, fs_hz, first_recording);
    recorded_s += rec.duration_s;
    RunOptions opts;
    opts.config_source = config_path;
    opts.progress_label = "train " + rec.dir.filename().string() + " (order domain, pass 1 of 3)";
    TrainingSpan span;
    span.begin = all.refs.size();
    const auto recording = static_cast<std::uint32_t>(spans.size());
    const std::uint64_t seq0 = seq_offset, segment0 = segment_offset;
    const OrderCollectResult c = collect_order_windows(
        rec, cfg, fs, opts, [&](const dsp::OrderWindowRef& r, std::span<const float> x) {
          dsp::OrderWindowRef ref = r;
          ref.seq += seq0;
          ref.segment += segment0;
          seq_offset = std::max(seq_offset, ref.seq + 1);
          segment_offset = std::max(segment_offset, ref.segment + 1);
          all.refs.push_back(ref);
          all.recording.push_back(recording);
          all.mean_square.push_back(dsp::window_mean_square(x));
        });
    span.end = all.refs.size();
    const dsp::AngleResamplerCounters& rc = c.resampler;
    out << "recording " << dir << ": " << fixed(rec.duration_s, 2) << " s at " << general(fs, 10) << " Hz, "
        << (span.end - span.begin) << " order windows (" << cfg.order.revolutions << " revolutions of "
        << cfg.order.samples_per_rev << " samples)\n";
    out << "  resampler: " << rc.frames << " angle frames, " << rc.breaks << " breaks, " << rc.frames_no_angle
        << " frames without angle, " << rc.angle_inconsistent << " inconsistent angle steps, "
        << rc.frames_out_of_order << " out of order; CAN: " << c.can.frames << " frames, "
        << c.can.speed_frames << " speed\n";
    source += " --recording " + dir;
    span.rec.id = recording_id(rec);
    span.rec.path = dir;
    spans.push_back(span);
    recs.push_back(rec);
  }
  source += " --config " + config_path;
  const std::size_t total = all.refs.size();
  const std::size_t first = static_cast<std::size_t>(range.first(total));
  const std::size_t last = static_cast<std::size_t>(range.last(total));
  const std::vector<dsp::TrainingRecording> training = training_recordings(spans, all.refs, first, last);
  if (!range.whole()) {
    dsp::OrderTrainingIndex kept(all.spill);
    dsp::SpillVector<dsp::OrderWindowRef>::Reader refs(all.refs);
    dsp::SpillVector<std::uint32_t>::Reader recording(all.recording);
    dsp::SpillVector<double>::Reader ms(all.mean_square);
    for (std::size_t i = 0; i < last; ++i) {
      const dsp::OrderWindowRef r = refs.next();
      const std::uint32_t rec = recording.next();
      const double m = ms.next();
      if (i < first) continue;
      kept.refs.push_back(r);
      kept.recording.push_back(rec);
      kept.mean_square.push_back(m);
    }
    all = std::move(kept);
    out << "windows " << a.value("windows") << ": kept " << all.refs.size() << " of " << total
        << " windows\n";
    source += " --windows " + a.value("windows");
  }
  if (all.refs.empty()) {
    out << "error: no order windows in the training recording(s) (" << cfg.order.revolutions
        << " revolutions of " << cfg.order.samples_per_rev
        << " samples): no unbroken run of motion that long; check the CAN angle and [extraction] "
           "revolutions\n";
    return kExitNotJudged;
  }
  // Two more passes over each recording hand the kept windows over in cut order.
  int pass_no = 1;
  const dsp::TrainingWindowPass pass = [&](const dsp::TrainingWindowVisitor& visit) {
    ++pass_no;
    dsp::SpillVector<dsp::OrderWindowRef>::Reader kept(all.refs);
    for (std::size_t r = 0; r < spans.size(); ++r) {
      const TrainingSpan& sp = spans[r];
      const std::uint64_t lo = std::max<std::uint64_t>(sp.begin, first);
      const std::uint64_t hi = std::min<std::uint64_t>(sp.end, first + all.refs.size());
      if (lo >= hi) continue;
      RunOptions opts;
      opts.config_source = config_path;
      opts.progress_label = "train " + recs[r].dir.filename().string() + " (order domain, pass " +
                            std::to_string(pass_no) + " of 3)";
      std::uint64_t cut = sp.begin;
      (void)collect_order_windows(
          recs[r], cfg, fs_hz, opts, [&](const dsp::OrderWindowRef& ref, std::span<const float> x) {
            const std::uint64_t g = cut++;
            if (g < lo || g >= hi) return;
            const auto i = static_cast<std::size_t>(g - first);
            if (kept.done() || kept.position() != i) {
              throw Error(recs[r].dir.string() + ": order window " + std::to_string(g - sp.begin) +
                          " is not in the first pass's cut order: did the recording change?");
            }
            const dsp::OrderWindowRef k = kept.next();
            if (ref.k_start != k.k_start || ref.t_start_ns != k.t_start_ns) {
              throw Error(recs[r].dir.string() + ": order window " + std::to_string(g - sp.begin) +
                          " is not where the first pass cut it (grid index " + std::to_string(ref.k_start) +
                          ", was " + std::to_string(k.k_start) + "): did the recording change?");
            }
            visit(i, x);
          });
      if (cut != sp.end) {
        throw Error(recs[r].dir.string() + ": " + std::to_string(cut - sp.begin) +
                    " order windows cut, the first pass cut " + std::to_string(sp.end - sp.begin) +
                    ": did the recording change?");
      }
    }
  };
  dsp::AngleResamplerConfig rc = config::angle_resampler_config(cfg);
  const dsp::OrderWindowConfig oc = config::order_window_config(cfg, dsp::AngleResampler::pass_order_of(rc));
  std::vector<std::string> dropped;
  dsp::Baseline baseline =
      dsp::train_order_baseline_streamed(all, pass, oc, cfg.order.speed_band_rel, cfg.thresholds, cfg.gearbox,
                                         &dropped, cfg.order.speed_law, cfg.classes.min_regions);
  // Windows per hour of recording, for the CUSUM's false-alarm rates per day (the time domain counts the
  // same; with --windows the kept fraction of the recorded time).
  const double kept_s = recorded_s * (range.whole() ? 1.0 : range.to - range.from);
  if (kept_s > 0.0) {
    for (dsp::ClassBaseline& c : baseline.classes) c.windows_per_hour = c.n_windows / (kept_s / 3600.0);
  }
  baseline.domain = dsp::Domain::kOrder;
  baseline.samples_per_rev = cfg.order.samples_per_rev;
  baseline.revolutions = cfg.order.revolutions;
  baseline.source = source;
  baseline.training = training;
  formats::write_baseline(a.value("out"), baseline);
  return print_trained(out, a.value("out"), baseline, cfg, fs_hz, dropped);
}

}  // namespace

int cmd_train(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "train", "--recording DIR [--recording DIR ...] --config FILE --out BASELINE [--windows FROM:TO]",
      "Cuts the constant-speed windows of healthy recordings exactly as `ptda monitor` does, groups the\n"
      "regions into segment classes (direction, speed), averages the windows of each class (TDA mean,\n"
      "PTDA mean magnitude) and sets the feature thresholds of every method from leave-one-cycle-out\n"
      "healthy features. Writes the binary baseline file.");
  parser.option("recording", "DIR", "healthy recording directory", true, true)
      .option("config", "FILE", "pipeline configuration TOML (extraction, classes, thresholds)", true)
      .option("out", "BASELINE", "baseline file to write (atomically)", true)
      .option("windows", "FROM:TO",
              "train on this fraction of the windows in cut order, e.g. 0:0.5 = the first half");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  FractionRange range;
  if (a.has("windows")) range = parse_fraction_range(a.value("windows"), "windows");
  const std::string config_path = a.value("config");
  const config::PipelineConfig cfg = config::load_pipeline_config(config_path);
  for (const std::string& w : cfg.warnings) std::cerr << "warning: " << w << "\n";
  if (cfg.domain == dsp::Domain::kOrder) return train_order(a, cfg, config_path, range, out);

  // The index of every window (place, recording) and the regions spill to $TMPDIR beyond 32 KiB per
  // list: with the streamed passes below, memory does not grow with the recordings' length.
  dsp::TrainingIndex all;
  IndexRenumber renumber;
  double fs_hz = 0.0;
  std::string first_recording;
  std::string source = "ptda train";
  // Each recording's windows are all.refs[begin, end): select_windows keeps one contiguous range.
  std::vector<TrainingSpan> spans;
  std::vector<RecordingInfo> recs;
  std::vector<DoctorReport> diagnoses;
  for (const auto& dir : a.values("recording")) {
    const RecordingInfo rec = open_recording(dir);
    const double fs = pipeline_fs_hz(rec, cfg, config_path);
    take_rate(rec, fs, dir, fs_hz, first_recording);
    RunOptions opts;
    opts.config_source = config_path;
    // Pass 0: the windows' places and the regions only; the samples come in the training's two passes.
    opts.progress_label = "train " + rec.dir.filename().string() + " (pass 1 of 3)";
    TrainingSpan span;
    span.begin = all.refs.size();
    const IndexResult c = index_windows(rec, cfg, fs, opts, all, renumber);
    span.end = all.refs.size();
    // The commissioning checks of `ptda doctor` (speed scale against the vibration, plateaus against
    // the window): a baseline on a wrong speed scale must not be written silently.
    diagnoses.push_back(diagnose_commissioning(rec, cfg, config_path, nullptr, ""));
    recs.push_back(rec);
    out << "recording " << dir << ": " << fixed(rec.duration_s, 2) << " s at " << general(fs, 10) << " Hz, "
        << c.regions << " constant-speed regions, " << c.windows << " windows\n";
    out << "  slicer: " << c.slicer.windows_invalid << " invalid and " << c.slicer.windows_lost
        << " lost windows (" << c.slicer.windows_overflow << " overflowed), " << c.slicer.speed_gaps
        << " speed gaps, " << c.slicer.speed_out_of_order
        << " out-of-order speed samples; CAN: " << c.can.frames << " frames, " << c.can.speed_frames
        << " speed, " << c.can.other_id << " other ids, " << c.can.wrong_dlc << " wrong DLC, "
        << c.can.error_frames << " error frames\n";
    source += " --recording " + dir;
    span.rec.id = recording_id(rec);
    span.rec.path = dir;
    spans.push_back(span);
  }
  // What each recording contributed after --windows, for `ptda monitor`'s in-sample warning.
  const std::vector<dsp::TrainingRecording> training =
      training_recordings(spans, all.refs, static_cast<std::size_t>(range.first(all.refs.size())),
                          static_cast<std::size_t>(range.last(all.refs.size())));
  source += " --config " + config_path;
  const std::uint64_t total_windows = all.refs.size();
  if (!range.whole()) {
    const std::uint64_t n = all.refs.size();
    all = select_windows(all, range);
    out << "windows " << a.value("windows") << ": kept " << all.refs.size() << " of " << n << " windows ("
        << all.regions.size() << " regions)\n";
    source += " --windows " + a.value("windows");
  }
  for (std::size_t i = 0; i < diagnoses.size(); ++i) {
    for (const DoctorFinding& f : diagnoses[i].findings) {
      if (f.kind == DoctorFinding::Kind::kProblem)
        out << "warning: " << recs[i].dir.string() << ": " << f.text << "\n";
    }
  }
  if (all.refs.empty()) {
    out << "error: no constant-speed windows in the training recording(s) (window_len "
        << cfg.extraction.window_len << ", min_duration_s " << general(cfg.extraction.min_duration_s)
        << "): nothing to train on; the warnings above say why (ptda doctor gives the whole check)\n";
    return kExitNotJudged;
  }
  for (std::size_t i = 0; i < diagnoses.size(); ++i) {
    if (diagnoses[i].scale.mismatch()) {
      out << "error: " << recs[i].dir.string() << ": not training on a wrong speed scale: "
          << scale_mismatch_text(diagnoses[i].scale, cfg, config_path) << "\n";
      return kExitCommissioning;
    }
  }

  // The training streams each recording twice more (the class sums, then the leave-one-group-out
  // features) instead of holding every window: memory does not grow with the recordings' length.
  const std::uint64_t kept_first = range.whole() ? 0 : range.first(total_windows);
  int pass_no = 1;
  const dsp::TrainingWindowPass pass = [&](const dsp::TrainingWindowVisitor& visit) {
    ++pass_no;
    dsp::SpillVector<dsp::WindowRef>::Reader kept(all.refs);  // the kept windows, in cut order
    for (std::size_t r = 0; r < spans.size(); ++r) {
      const TrainingSpan& sp = spans[r];
      const std::uint64_t lo = std::max<std::uint64_t>(sp.begin, kept_first);
      const std::uint64_t hi = std::min<std::uint64_t>(sp.end, kept_first + all.refs.size());
      if (lo >= hi) continue;  // none of this recording's windows is trained on
      RunOptions opts;
      opts.config_source = config_path;
      opts.progress_label =
          "train " + recs[r].dir.filename().string() + " (pass " + std::to_string(pass_no) + " of 3)";
      std::uint64_t cut = sp.begin;  // index of the next window in the whole cut order
      (void)collect_windows(
          recs[r], cfg, fs_hz, opts, [&](const dsp::WindowRef& ref, std::span<const float> x) {
            const std::uint64_t g = cut++;
            if (g < lo || g >= hi) return;
            const auto i = static_cast<std::size_t>(g - kept_first);
            if (kept.done() || kept.position() != i) {
              throw Error(recs[r].dir.string() + ": window " + std::to_string(g - sp.begin) +
                          " is not in the first pass's cut order: did the recording change?");
            }
            const dsp::WindowRef k = kept.next();
            if (ref.first_sample != k.first_sample || ref.t_start_ns != k.t_start_ns) {
              throw Error(recs[r].dir.string() + ": window " + std::to_string(g - sp.begin) +
                          " is not where the first pass cut it (sample " + std::to_string(ref.first_sample) +
                          ", was " + std::to_string(k.first_sample) + "): did the recording change?");
            }
            visit(i, x);
          });
      if (cut != sp.end) {
        throw Error(recs[r].dir.string() + ": " + std::to_string(cut - sp.begin) +
                    " windows cut, the first pass cut " + std::to_string(sp.end - sp.begin) +
                    ": did the recording change?");
      }
    }
  };
  std::vector<std::string> dropped;
  dsp::Baseline baseline = dsp::train_baseline_streamed(all, cfg.extraction.window_len, pass, cfg.classes,
                                                        cfg.thresholds, fs_hz, cfg.gearbox, &dropped);
  baseline.source = source;
  baseline.training = training;
  formats::write_baseline(a.value("out"), baseline);

  return print_trained(out, a.value("out"), baseline, cfg, fs_hz, dropped);
}

}  // namespace ptda::cli
