// gap-bench case generation and scoring.
#include "ptda/gap/bench.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "ptda/common/error.hpp"
#include "ptda/sim/random.hpp"

namespace ptda::gap {
namespace {

using sim::EffectKind;
using sim::EffectSpec;

constexpr std::uint64_t kStreamBench = 0xBE7C;

double uni(sim::Rng& r, double lo, double hi) {
  return lo + (hi - lo) * r.uniform();
}

EffectSpec random_effect(EffectKind k, sim::Rng& r, double fs, double peak_ms2, const sim::Scenario& job) {
  EffectSpec e = EffectSpec::with_defaults(k);
  switch (k) {
    case EffectKind::kTransferPath:
      e.set("frequency_hz", std::exp(uni(r, std::log(800.0), std::log(0.38 * fs))));
      e.set("gain_db", uni(r, 8, 20));
      e.set("q", uni(r, 3, 10));
      break;
    case EffectKind::kSpeedRipple:
      e.set("jitter_rad", uni(r, 0.25, 0.8));
      e.set("bandwidth_hz", std::exp(uni(r, std::log(5.0), std::log(50.0))));
      break;
    case EffectKind::kMeshModulation:
      e.set("rate_order", uni(r, 0.6, 3.0));
      e.set("am_depth", uni(r, 0.15, 0.5));
      e.set("pm_rad", r.uniform() < 0.5 ? 0.0 : uni(r, 0.05, 0.3));
      break;
    case EffectKind::kImpacts:
      e.set("amplitude_ms2", uni(r, 3, 15));
      e.set("resonance_hz", std::exp(uni(r, std::log(1000.0), std::log(0.38 * fs))));
      e.set("damping_ratio", uni(r, 0.03, 0.1));
      break;
    case EffectKind::kElectricalInterference:
      e.set("frequency_hz", std::exp(uni(r, std::log(40.0), std::log(400.0))));
      e.set("amplitude_ms2", uni(r, 0.05, 0.5));
      e.set("harmonics", std::floor(uni(r, 1, 6)));
      e.set("harmonic_decay", uni(r, 0.3, 0.8));
      break;
    case EffectKind::kAdcClipping:
      e.set("level_ms2", uni(r, 0.5, 0.8) * peak_ms2);
      break;
    case EffectKind::kSampleClockError: {
      const double m = uni(r, 300, 3000);
      e.set("ppm", r.uniform() < 0.5 ? -m : m);
      break;
    }
    case EffectKind::kSpeedLatency:
      e.set("delay_s", uni(r, 0.01, 0.05));
      e.set("jitter_s", std::min(uni(r, 0.0, 0.002), 0.9 * (job.can.period_s - job.can.jitter_s)));
      break;
    case EffectKind::kOtherAxis: {
      double ratio = 1.0;
      while (std::fabs(ratio - std::round(ratio)) < 0.1) ratio = uni(r, 0.3, 2.5);
      e.set("amplitude_ms2", uni(r, 0.2, 1.0));
      e.set("frequency_ratio", ratio);
      e.set("lag_s", uni(r, 0.0, 0.2));
      break;
    }
    case EffectKind::kLoadDependence: {
      const double g = uni(r, 0.2, 0.5);
      e.set("direction_gain", r.uniform() < 0.5 ? -g : g);
      e.set("accel_gain", uni(r, -0.3, 0.3));
      break;
    }
    case EffectKind::kNoiseColor:
      e.set("rms_ms2", uni(r, 0.6, 2.0) * std::max(job.vibration.noise_rms, 0.05));
      e.set("corner_hz", std::exp(uni(r, std::log(30.0), std::log(500.0))));
      break;
  }
  return e;
}

double rel(double a, double b) {
  return std::fabs(a / b - 1.0);
}

std::string num(double v) {
  if (!std::isfinite(v)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

std::string effects_json(const std::vector<EffectSpec>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) {
    const sim::EffectInfo& info = sim::effect_info(v[i].kind);
    s += std::string(i ? ", " : "") + "{\"kind\": \"" + info.name + "\", \"params\": {";
    for (std::size_t p = 0; p < info.params.size(); ++p) {
      s += std::string(p ? ", " : "") + "\"" + info.params[p].name + "\": " + num(v[i].params[p]);
    }
    s += "}}";
  }
  return s + "]";
}

}  // namespace

std::vector<EffectSpec> bench_case_effects(std::uint32_t index, std::uint64_t seed, double fs_hz,
                                           double peak_ms2, const sim::Scenario& job) {
  sim::Rng r(seed * 1000003ULL + index, kStreamBench);
  const std::uint32_t slots = sim::kEffectKinds + 2;
  const std::uint32_t slot = index % slots;
  std::vector<EffectSpec> out;
  if (slot < sim::kEffectKinds) {
    out.push_back(random_effect(static_cast<EffectKind>(slot), r, fs_hz, peak_ms2, job));
  } else if (slot == sim::kEffectKinds + 1) {
    // A pair of different effects, drawn at random.
    const auto a = static_cast<std::uint32_t>(r.uniform() * sim::kEffectKinds);
    auto b = static_cast<std::uint32_t>(r.uniform() * (sim::kEffectKinds - 1));
    if (b >= a) ++b;
    out.push_back(random_effect(static_cast<EffectKind>(a), r, fs_hz, peak_ms2, job));
    out.push_back(random_effect(static_cast<EffectKind>(b), r, fs_hz, peak_ms2, job));
  }
  return out;
}

bool location_matches(const EffectSpec& t, const EffectSpec& f) {
  if (t.kind != f.kind) return false;
  switch (t.kind) {
    case EffectKind::kTransferPath:
      return rel(f.get("frequency_hz"), t.get("frequency_hz")) < 0.15;
    case EffectKind::kSpeedRipple:
      return f.get("jitter_rad") > 0.5 * t.get("jitter_rad") &&
             f.get("jitter_rad") < 2.0 * t.get("jitter_rad");
    case EffectKind::kMeshModulation:
      return std::fabs(f.get("rate_order") - t.get("rate_order")) < 0.15;
    case EffectKind::kImpacts:
      return rel(f.get("resonance_hz"), t.get("resonance_hz")) < 0.2;
    case EffectKind::kElectricalInterference:
      return rel(f.get("frequency_hz"), t.get("frequency_hz")) < 0.02;
    case EffectKind::kAdcClipping:
      return rel(f.get("level_ms2"), t.get("level_ms2")) < 0.05;
    case EffectKind::kSampleClockError:
      return std::fabs(f.get("ppm") - t.get("ppm")) < std::max(100.0, 0.2 * std::fabs(t.get("ppm")));
    case EffectKind::kSpeedLatency:
      return std::fabs(f.get("delay_s") - t.get("delay_s")) < 0.005;
    case EffectKind::kOtherAxis:
      return rel(f.get("frequency_ratio"), t.get("frequency_ratio")) < 0.02;
    case EffectKind::kLoadDependence:
      return f.get("direction_gain") * t.get("direction_gain") > 0.0;
    case EffectKind::kNoiseColor:
      return f.get("corner_hz") > 0.5 * t.get("corner_hz") && f.get("corner_hz") < 2.0 * t.get("corner_hz");
  }
  return false;
}

BenchResult run_bench(const BenchOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  if (opt.jobs.empty()) throw Error("gap-bench: no job presets given");
  BenchResult res;
  res.confusion.assign(sim::kEffectKinds + 1, std::vector<std::uint32_t>(sim::kEffectKinds + 1, 0));
  std::filesystem::create_directories(opt.work_dir);
  std::vector<double> shrinks;
  std::uint32_t correct = 0, located = 0, false_attr = 0;
  for (std::uint32_t i = 0; i < opt.cases; ++i) {
    if (!opt.only.empty() && std::find(opt.only.begin(), opt.only.end(), i) == opt.only.end()) continue;
    BenchCaseResult cr;
    cr.index = i;
    const std::filesystem::path job_path = opt.jobs[i % opt.jobs.size()];
    cr.job = job_path.filename().string();
    sim::Scenario nominal = sim::load_scenario(job_path);
    nominal.motion.cycles = opt.cycles;
    // Short recordings keep the bench fast: long rests add little but standstill windows.
    nominal.motion.dwell_s = std::min(nominal.motion.dwell_s, 0.5);
    nominal.effects.clear();
    sim::Rng r(opt.seed * 7919ULL + i, kStreamBench + 1);
    cr.seed = 100000 + opt.seed * 1000 + i;
    // The "real" machine: the nominal job with other amplitudes and noise, other seed, plus the effects.
    sim::Scenario real = nominal;
    for (double& a : real.vibration.gmf_amplitudes) a *= uni(r, 0.7, 1.4);
    real.vibration.noise_rms *= uni(r, 0.7, 1.4);
    double peak = 0.0;
    {
      const sim::SimulatedSignals probe = sim::simulate_signals(real, cr.seed);
      for (double v : probe.vibration.accel_ms2) peak = std::max(peak, std::fabs(v));
    }
    cr.truth = bench_case_effects(i, opt.seed, nominal.sensor.fs_hz, peak, nominal);
    real.effects = cr.truth;
    const std::filesystem::path dir = opt.work_dir / ("case" + std::to_string(i));
    (void)sim::simulate_to_directory(real, dir, cr.seed);
    const GapRecording rec = load_recording(dir, nominal.can.speed_frame, nominal.can.delay_s);
    DiagnoseOptions dopt;
    dopt.sim_seed = 424242 + opt.seed;
    dopt.threads = opt.threads;
    const Diagnosis d = diagnose(nominal, rec, dopt);
    for (const CandidateResult& c : d.chosen) cr.chosen.push_back(c.effect);
    cr.shrink_pct = d.total_shrink_pct;
    cr.gap_heldout = d.nominal_heldout.total;
    cr.noise_gap = d.noise_gap;
    cr.noise_gap_sd = d.noise_gap_sd;
    cr.runtime_s = d.runtime_s;
    cr.verdict = d.verdict;
    const std::size_t named =
        cr.chosen.empty() ? sim::kEffectKinds : static_cast<std::size_t>(cr.chosen[0].kind);
    if (cr.truth.empty()) {
      ++res.none_cases;
      cr.false_attribution = !cr.chosen.empty();
      cr.top1_correct = cr.chosen.empty();
      false_attr += cr.false_attribution ? 1U : 0U;
      res.confusion[sim::kEffectKinds][named] += 1;
    } else {
      ++res.effect_cases;
      for (const EffectSpec& t : cr.truth) {
        if (!cr.chosen.empty() && cr.chosen[0].kind == t.kind) {
          cr.top1_correct = true;
          cr.location_ok = location_matches(t, cr.chosen[0]);
        }
      }
      correct += cr.top1_correct ? 1U : 0U;
      located += cr.location_ok ? 1U : 0U;
      shrinks.push_back(cr.shrink_pct);
      // Pairs count under their first effect, or the one named when it is either.
      std::size_t ti = static_cast<std::size_t>(cr.truth[0].kind);
      for (const EffectSpec& t : cr.truth) {
        if (static_cast<std::size_t>(t.kind) == named) ti = named;
      }
      res.confusion[ti][named] += 1;
    }
    if (opt.log) {
      std::string t, c;
      for (const EffectSpec& e : cr.truth) t += sim::describe(e) + " ";
      for (const EffectSpec& e : cr.chosen) c += sim::describe(e) + " ";
      opt.log("case " + std::to_string(i) + " [" + cr.job + "] truth: " + (t.empty() ? "none " : t) +
              "| named: " + (c.empty() ? "none " : c) + "| " + (cr.top1_correct ? "OK" : "WRONG") +
              (cr.location_ok ? " located" : "") + " shrink " + num(cr.shrink_pct) + " % gap " +
              num(cr.gap_heldout) + " expected " + num(cr.noise_gap) + " +- " + num(cr.noise_gap_sd) + " (" +
              num(cr.runtime_s) + " s)");
    }
    if (!opt.keep_recordings) std::filesystem::remove_all(dir);
    res.cases.push_back(std::move(cr));
  }
  res.top1_accuracy = res.effect_cases ? static_cast<double>(correct) / res.effect_cases : 0.0;
  res.location_accuracy = correct ? static_cast<double>(located) / correct : 0.0;
  res.false_attribution_rate = res.none_cases ? static_cast<double>(false_attr) / res.none_cases : 0.0;
  if (!shrinks.empty()) {
    std::sort(shrinks.begin(), shrinks.end());
    const std::size_t n = shrinks.size();
    res.median_shrink_pct = n % 2 ? shrinks[n / 2] : 0.5 * (shrinks[n / 2 - 1] + shrinks[n / 2]);
  }
  res.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

std::string bench_json(const BenchResult& r) {
  std::ostringstream o;
  o << "{\n  \"format\": \"ptda-gap-bench\",\n  \"version\": 1,\n";
  o << "  \"effect_cases\": " << r.effect_cases << ",\n  \"none_cases\": " << r.none_cases << ",\n";
  o << "  \"top1_accuracy\": " << num(r.top1_accuracy)
    << ",\n  \"location_accuracy\": " << num(r.location_accuracy)
    << ",\n  \"false_attribution_rate\": " << num(r.false_attribution_rate)
    << ",\n  \"median_shrink_pct\": " << num(r.median_shrink_pct)
    << ",\n  \"runtime_s\": " << num(r.runtime_s) << ",\n";
  o << "  \"labels\": [";
  for (std::size_t k = 0; k <= sim::kEffectKinds; ++k) {
    o << (k ? ", " : "") << "\""
      << (k < sim::kEffectKinds ? sim::effect_info(static_cast<EffectKind>(k)).name : "none") << "\"";
  }
  o << "],\n  \"confusion\": [";
  for (std::size_t t = 0; t < r.confusion.size(); ++t) {
    o << (t ? ",\n    " : "\n    ") << "[";
    for (std::size_t p = 0; p < r.confusion[t].size(); ++p) o << (p ? ", " : "") << r.confusion[t][p];
    o << "]";
  }
  o << "\n  ],\n  \"cases\": [";
  for (std::size_t i = 0; i < r.cases.size(); ++i) {
    const BenchCaseResult& c = r.cases[i];
    o << (i ? "," : "") << "\n    {\"index\": " << c.index << ", \"job\": \"" << c.job
      << "\", \"seed\": " << c.seed << ", \"truth\": " << effects_json(c.truth)
      << ", \"chosen\": " << effects_json(c.chosen)
      << ", \"top1_correct\": " << (c.top1_correct ? "true" : "false")
      << ", \"location_ok\": " << (c.location_ok ? "true" : "false")
      << ", \"false_attribution\": " << (c.false_attribution ? "true" : "false")
      << ", \"shrink_pct\": " << num(c.shrink_pct) << ", \"gap_heldout\": " << num(c.gap_heldout)
      << ", \"noise_gap\": " << num(c.noise_gap) << ", \"noise_gap_sd\": " << num(c.noise_gap_sd)
      << ", \"runtime_s\": " << num(c.runtime_s) << "}";
  }
  o << "\n  ]\n}\n";
  return o.str();
}

}  // namespace ptda::gap
