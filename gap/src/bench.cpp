// gap-bench case generation and scoring.
#include "ptda/gap/bench.hpp"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
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

constexpr std::size_t kConfusionRows = sim::kEffectKinds + 2;  // + control (none), + out of library

// What the bench keeps of a diagnosis (passed from the forked child as text).
struct Outcome {
  std::vector<EffectSpec> chosen;
  double shrink_pct = 0.0, gap_heldout = 0.0, noise_gap = 0.0, noise_gap_sd = 0.0, runtime_s = 0.0;
  double peak_rss_mib = 0.0, remaining_share = 0.0, cpu_s = 0.0;
  std::string remaining_probe, verdict, error;
};

double cpu_seconds(const rusage& ru) {
  return static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

Outcome outcome_of(const Diagnosis& d) {
  Outcome o;
  for (const CandidateResult& c : d.chosen) o.chosen.push_back(c.effect);
  o.shrink_pct = d.total_shrink_pct;
  o.gap_heldout = d.nominal_heldout.total;
  o.noise_gap = d.noise_gap;
  o.noise_gap_sd = d.noise_gap_sd;
  o.runtime_s = d.runtime_s;
  o.verdict = d.verdict;
  const GapBreakdown& rest = d.chosen.empty() ? d.nominal_heldout : d.final_heldout;
  double best = -1.0;
  for (const auto& [probe, g] : rest.by_probe) {
    if (g > best) {
      best = g;
      o.remaining_probe = probe;
    }
  }
  o.remaining_share = rest.total > 0.0 && best > 0.0 ? best / rest.total : 0.0;
  return o;
}

std::string one_line(std::string s) {
  std::replace(s.begin(), s.end(), '\n', ' ');
  return s;
}

// Text form: one "key value" per line; effects as "effect KIND_INDEX N p1 .. pN" (%.17g round trips).
std::string serialise(const Outcome& o) {
  std::ostringstream w;
  w.precision(17);
  if (!o.error.empty()) {
    w << "error " << one_line(o.error) << "\n";
    return w.str();
  }
  for (const EffectSpec& e : o.chosen) {
    w << "effect " << static_cast<unsigned>(e.kind) << " " << e.params.size();
    for (double v : e.params) w << " " << v;
    w << "\n";
  }
  w << "shrink " << o.shrink_pct << "\ngap " << o.gap_heldout << "\nnoise " << o.noise_gap << "\nsd "
    << o.noise_gap_sd << "\nruntime " << o.runtime_s << "\nrest " << o.remaining_share << " "
    << (o.remaining_probe.empty() ? "-" : o.remaining_probe) << "\nverdict " << one_line(o.verdict) << "\n";
  return w.str();
}

Outcome deserialise(const std::string& text) {
  Outcome o;
  std::istringstream in(text);
  bool any = false;
  for (std::string line; std::getline(in, line);) {
    const std::size_t sp = line.find(' ');
    const std::string key = line.substr(0, sp);
    const std::string rest = sp == std::string::npos ? "" : line.substr(sp + 1);
    std::istringstream v(rest);
    any = true;
    if (key == "error") {
      o.error = rest;
    } else if (key == "effect") {
      unsigned kind = 0;
      std::size_t n = 0;
      v >> kind >> n;
      if (kind >= sim::kEffectKinds) throw Error("gap-bench: bad effect kind from the diagnosis process");
      EffectSpec e = EffectSpec::with_defaults(static_cast<EffectKind>(kind));
      e.params.assign(n, 0.0);
      for (double& p : e.params) v >> p;
      o.chosen.push_back(std::move(e));
    } else if (key == "shrink") {
      v >> o.shrink_pct;
    } else if (key == "gap") {
      v >> o.gap_heldout;
    } else if (key == "noise") {
      v >> o.noise_gap;
    } else if (key == "sd") {
      v >> o.noise_gap_sd;
    } else if (key == "runtime") {
      v >> o.runtime_s;
    } else if (key == "rest") {
      v >> o.remaining_share >> o.remaining_probe;
      if (o.remaining_probe == "-") o.remaining_probe.clear();
    } else if (key == "verdict") {
      o.verdict = rest;
    }
  }
  if (!any) o.error = "the diagnosis process produced no result";
  return o;
}

// Runs one diagnosis in a forked child so that its peak resident memory (wait4's ru_maxrss) is its
// own; falls back to running in-process (peak of the whole process so far) when fork fails.
Outcome run_isolated(const std::function<Diagnosis()>& fn) {
  auto in_process = [&] {
    Outcome o;
    try {
      o = outcome_of(fn());
    } catch (const std::exception& e) {
      o.error = e.what();
    }
    rusage ru{};
    if (getrusage(RUSAGE_SELF, &ru) == 0) {
      o.peak_rss_mib = static_cast<double>(ru.ru_maxrss) / 1024.0;
      o.cpu_s = cpu_seconds(ru);  // of the whole process so far (fallback only)
    }
    return o;
  };
  int fds[2];
  if (pipe(fds) != 0) return in_process();
  const pid_t pid = fork();
  if (pid < 0) {
    close(fds[0]);
    close(fds[1]);
    return in_process();
  }
  if (pid == 0) {
    close(fds[0]);
    Outcome o;
    try {
      o = outcome_of(fn());
    } catch (const std::exception& e) {
      o.error = e.what();
    }
    const std::string text = serialise(o);
    std::size_t off = 0;
    while (off < text.size()) {
      const ssize_t w = write(fds[1], text.data() + off, text.size() - off);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) _exit(3);
      off += static_cast<std::size_t>(w);
    }
    close(fds[1]);
    _exit(0);
  }
  close(fds[1]);
  std::string text;
  char buf[4096];
  for (;;) {
    const ssize_t n = read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    text.append(buf, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  rusage ru{};
  while (wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
  }
  Outcome o = deserialise(text);
  if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0) && o.error.empty()) {
    o.error = WIFSIGNALED(status)
                  ? "the diagnosis process died with signal " + std::to_string(WTERMSIG(status))
                  : "the diagnosis process failed";
  }
  o.peak_rss_mib = static_cast<double>(ru.ru_maxrss) / 1024.0;
  o.cpu_s = cpu_seconds(ru);
  return o;
}

void take(BenchCaseResult& cr, Outcome o) {
  cr.chosen = std::move(o.chosen);
  cr.shrink_pct = o.shrink_pct;
  cr.gap_heldout = o.gap_heldout;
  cr.noise_gap = o.noise_gap;
  cr.noise_gap_sd = o.noise_gap_sd;
  cr.runtime_s = o.runtime_s;
  cr.peak_rss_mib = o.peak_rss_mib;
  cr.cpu_s = o.cpu_s;
  cr.remaining_probe = std::move(o.remaining_probe);
  cr.remaining_share = o.remaining_share;
  cr.verdict = std::move(o.verdict);
  cr.error = std::move(o.error);
}

}  // namespace

bool named_and_located(const std::vector<EffectSpec>& truth, const std::vector<EffectSpec>& chosen) {
  for (const EffectSpec& t : truth) {
    for (const EffectSpec& c : chosen) {
      if (c.kind == t.kind && location_matches(t, c)) return true;
    }
  }
  return false;
}

namespace {

// Scores one case into the totals (docs/gap.md "Bench"): top-1 = first named effect is a true one;
// controls and out-of-library cases are right when nothing is named.
void score(BenchResult& res, BenchCaseResult& cr, std::vector<double>& shrinks,
           std::vector<double>& runtimes) {
  const std::size_t named =
      cr.chosen.empty() ? sim::kEffectKinds : static_cast<std::size_t>(cr.chosen[0].kind);
  if (!cr.error.empty()) ++res.errors;
  if (cr.error.empty()) {
    runtimes.push_back(cr.runtime_s);
    res.max_case_cpu_s = std::max(res.max_case_cpu_s, cr.cpu_s);
  }
  res.max_peak_rss_mib = std::max(res.max_peak_rss_mib, cr.peak_rss_mib);
  if (cr.category != CaseCategory::kEffect) {
    const bool ool = cr.category == CaseCategory::kOutOfLibrary;
    cr.false_attribution = !cr.chosen.empty();
    cr.top1_correct = cr.chosen.empty() && cr.error.empty();
    if (ool) {
      ++res.ool_cases;
      res.ool_false_attributions += cr.false_attribution ? 1U : 0U;
    } else {
      ++res.none_cases;
      res.false_attributions += cr.false_attribution ? 1U : 0U;
    }
    res.confusion[ool ? sim::kEffectKinds + 1 : sim::kEffectKinds][named] += 1;
    return;
  }
  ++res.effect_cases;
  for (const EffectSpec& t : cr.truth) {
    if (!cr.chosen.empty() && cr.chosen[0].kind == t.kind) {
      cr.top1_correct = true;
      cr.location_ok = location_matches(t, cr.chosen[0]);
    }
  }
  cr.named_located = named_and_located(cr.truth, cr.chosen);
  res.top1_correct += cr.top1_correct ? 1U : 0U;
  res.located += cr.location_ok ? 1U : 0U;
  res.named_located += cr.named_located ? 1U : 0U;
  shrinks.push_back(cr.shrink_pct);
  // Pairs count under their first effect, or the one named when it is either.
  std::size_t ti = cr.truth.empty() ? sim::kEffectKinds : static_cast<std::size_t>(cr.truth[0].kind);
  for (const EffectSpec& t : cr.truth) {
    if (static_cast<std::size_t>(t.kind) == named) ti = named;
  }
  res.confusion[ti][named] += 1;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void finish(BenchResult& res, const std::vector<double>& shrinks, const std::vector<double>& runtimes) {
  res.top1_accuracy = res.effect_cases ? static_cast<double>(res.top1_correct) / res.effect_cases : 0.0;
  res.location_accuracy = res.top1_correct ? static_cast<double>(res.located) / res.top1_correct : 0.0;
  res.false_attribution_rate =
      res.none_cases ? static_cast<double>(res.false_attributions) / res.none_cases : 0.0;
  res.ool_false_attribution_rate =
      res.ool_cases ? static_cast<double>(res.ool_false_attributions) / res.ool_cases : 0.0;
  res.median_shrink_pct = median(shrinks);
  res.median_case_runtime_s = median(runtimes);
  res.max_case_runtime_s = runtimes.empty() ? 0.0 : *std::max_element(runtimes.begin(), runtimes.end());
}

std::string case_line(const BenchCaseResult& cr) {
  std::string t, c;
  for (const EffectSpec& e : cr.truth) t += sim::describe(e) + " ";
  if (t.empty())
    t = std::string(cr.category == CaseCategory::kOutOfLibrary ? "out of library" : "none") + " ";
  for (const EffectSpec& e : cr.chosen) c += sim::describe(e) + " ";
  std::string line = cr.name + " [" + cr.job + "] truth: " + t + "| named: " + (c.empty() ? "none " : c) +
                     "| " + (cr.top1_correct ? "OK" : "WRONG") + (cr.location_ok ? " located" : "") +
                     (!cr.top1_correct && cr.named_located ? " (named later, located)" : "") + " shrink " +
                     num(cr.shrink_pct) + " % gap " + num(cr.gap_heldout) + " expected " + num(cr.noise_gap) +
                     " +- " + num(cr.noise_gap_sd) + " (" + num(cr.runtime_s) + " s, " +
                     num(cr.peak_rss_mib) + " MiB, cpu " + num(cr.cpu_s) + " s)";
  if (!cr.error.empty()) line += " ERROR: " + cr.error;
  return line;
}

std::string json_str(const std::string& v) {
  std::string s = "\"";
  for (char ch : v) {
    const auto c = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') {
      s += '\\';
      s += ch;
    } else if (c < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", c);
      s += b;
    } else {
      s += ch;
    }
  }
  return s + "\"";
}

std::string row_label(std::size_t k) {
  if (k < sim::kEffectKinds) return sim::effect_info(static_cast<EffectKind>(k)).name;
  return k == sim::kEffectKinds ? "none" : "out_of_library";
}

const char* short_label(std::size_t k) {
  static constexpr const char* kShort[] = {"tp",    "ripple",  "modul.", "impacts", "elec.", "clip",
                                           "clock", "latency", "other",  "load",    "color", "none"};
  static_assert(sizeof kShort / sizeof kShort[0] == sim::kEffectKinds + 1);
  return kShort[k];
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
    case EffectKind::kOtherAxis: {
      // Another axis on its own program is located by its line; the lagged form by its ratio to this
      // GMF. One form named for the other is not located (a fixed line has no ratio to compare).
      const double t_own = t.get("own_frequency_hz"), f_own = f.get("own_frequency_hz");
      if (t_own > 0.0) return f_own > 0.0 && rel(f_own, t_own) < 0.02;
      return f_own <= 0.0 && rel(f.get("frequency_ratio"), t.get("frequency_ratio")) < 0.02;
    }
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
  res.confusion.assign(kConfusionRows, std::vector<std::uint32_t>(sim::kEffectKinds + 1, 0));
  std::filesystem::create_directories(opt.work_dir);
  std::vector<double> shrinks, runtimes;
  for (std::uint32_t i = 0; i < opt.cases; ++i) {
    if (!opt.only.empty() && std::find(opt.only.begin(), opt.only.end(), i) == opt.only.end()) continue;
    BenchCaseResult cr;
    cr.index = i;
    cr.name = "case" + std::to_string(i);
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
    cr.category = cr.truth.empty() ? CaseCategory::kControl : CaseCategory::kEffect;
    real.effects = cr.truth;
    const std::filesystem::path dir = opt.work_dir / ("case" + std::to_string(i));
    (void)sim::simulate_to_directory(real, dir, cr.seed);
    DiagnoseOptions dopt;
    dopt.sim_seed = 424242 + opt.seed;
    dopt.threads = opt.threads;
    take(cr, run_isolated([&] {
           const GapRecording rec = load_recording(dir, nominal.can.speed_frame, nominal.can.delay_s);
           return diagnose(nominal, rec, dopt);
         }));
    score(res, cr, shrinks, runtimes);
    if (opt.log) opt.log(case_line(cr));
    if (!opt.keep_recordings) std::filesystem::remove_all(dir);
    res.cases.push_back(std::move(cr));
  }
  finish(res, shrinks, runtimes);
  res.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

BenchResult run_corpus_bench(const Corpus& corpus, const CorpusBenchOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  BenchResult res;
  res.corpus = corpus.name;
  res.confusion.assign(kConfusionRows, std::vector<std::uint32_t>(sim::kEffectKinds + 1, 0));
  std::vector<double> shrinks, runtimes;
  for (std::size_t i = 0; i < corpus.cases.size(); ++i) {
    const CorpusCase& cc = corpus.cases[i];
    if (!opt.only.empty() && std::find(opt.only.begin(), opt.only.end(), cc.name) == opt.only.end()) continue;
    BenchCaseResult cr;
    cr.index = static_cast<std::uint32_t>(i);
    cr.name = cc.name;
    cr.category = cc.category;
    cr.description = cc.description;
    cr.job = cc.nominal.filename().string();
    cr.truth = cc.truth;
    DiagnoseOptions dopt;
    dopt.sim_seed = opt.sim_seed;
    dopt.threads = opt.threads;
    take(cr, run_isolated([&] {
           const sim::Scenario nominal = sim::load_scenario(cc.nominal);
           const GapRecording rec =
               load_recording(cc.recording, nominal.can.speed_frame, nominal.can.delay_s);
           return diagnose(nominal, rec, dopt);
         }));
    score(res, cr, shrinks, runtimes);
    if (opt.log) opt.log(case_line(cr));
    res.cases.push_back(std::move(cr));
  }
  finish(res, shrinks, runtimes);
  res.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

const char* case_category_name(CaseCategory c) noexcept {
  switch (c) {
    case CaseCategory::kEffect:
      return "effect";
    case CaseCategory::kControl:
      return "control";
    case CaseCategory::kOutOfLibrary:
      return "out_of_library";
  }
  return "?";
}

std::string bench_json(const BenchResult& r) {
  std::ostringstream o;
  o << "{\n  \"format\": \"ptda-gap-bench\",\n  \"version\": 1,\n  \"corpus\": " << json_str(r.corpus)
    << ",\n";
  o << "  \"effect_cases\": " << r.effect_cases << ",\n  \"none_cases\": " << r.none_cases
    << ",\n  \"out_of_library_cases\": " << r.ool_cases << ",\n  \"errors\": " << r.errors << ",\n";
  o << "  \"top1_accuracy\": " << num(r.top1_accuracy)
    << ",\n  \"location_accuracy\": " << num(r.location_accuracy) << ",\n  \"named_located_rate\": "
    << num(r.effect_cases ? static_cast<double>(r.named_located) / r.effect_cases : 0.0)
    << ",\n  \"false_attribution_rate\": " << num(r.false_attribution_rate)
    << ",\n  \"out_of_library_false_attribution_rate\": " << num(r.ool_false_attribution_rate)
    << ",\n  \"median_shrink_pct\": " << num(r.median_shrink_pct)
    << ",\n  \"median_case_runtime_s\": " << num(r.median_case_runtime_s)
    << ",\n  \"max_case_runtime_s\": " << num(r.max_case_runtime_s)
    << ",\n  \"max_case_cpu_s\": " << num(r.max_case_cpu_s)
    << ",\n  \"max_peak_rss_mib\": " << num(r.max_peak_rss_mib) << ",\n  \"runtime_s\": " << num(r.runtime_s)
    << ",\n";
  o << "  \"labels\": [";
  for (std::size_t k = 0; k <= sim::kEffectKinds; ++k) {
    o << (k ? ", " : "") << "\""
      << (k < sim::kEffectKinds ? sim::effect_info(static_cast<EffectKind>(k)).name : "none") << "\"";
  }
  o << "],\n  \"row_labels\": [";
  for (std::size_t k = 0; k < kConfusionRows; ++k) o << (k ? ", " : "") << "\"" << row_label(k) << "\"";
  o << "],\n  \"confusion\": [";
  for (std::size_t t = 0; t < r.confusion.size(); ++t) {
    o << (t ? ",\n    " : "\n    ") << "[";
    for (std::size_t p = 0; p < r.confusion[t].size(); ++p) o << (p ? ", " : "") << r.confusion[t][p];
    o << "]";
  }
  o << "\n  ],\n  \"cases\": [";
  for (std::size_t i = 0; i < r.cases.size(); ++i) {
    const BenchCaseResult& c = r.cases[i];
    o << (i ? "," : "") << "\n    {\"index\": " << c.index << ", \"name\": " << json_str(c.name)
      << ", \"category\": \"" << case_category_name(c.category)
      << "\", \"description\": " << json_str(c.description) << ", \"job\": " << json_str(c.job)
      << ", \"seed\": " << c.seed << ", \"truth\": " << effects_json(c.truth)
      << ", \"chosen\": " << effects_json(c.chosen)
      << ", \"top1_correct\": " << (c.top1_correct ? "true" : "false")
      << ", \"location_ok\": " << (c.location_ok ? "true" : "false")
      << ", \"named_located\": " << (c.named_located ? "true" : "false")
      << ", \"false_attribution\": " << (c.false_attribution ? "true" : "false")
      << ", \"shrink_pct\": " << num(c.shrink_pct) << ", \"gap_heldout\": " << num(c.gap_heldout)
      << ", \"noise_gap\": " << num(c.noise_gap) << ", \"noise_gap_sd\": " << num(c.noise_gap_sd)
      << ", \"runtime_s\": " << num(c.runtime_s) << ", \"peak_rss_mib\": " << num(c.peak_rss_mib)
      << ", \"cpu_s\": " << num(c.cpu_s) << ", \"remaining_probe\": " << json_str(c.remaining_probe)
      << ", \"remaining_share\": " << num(c.remaining_share) << ", \"verdict\": " << json_str(c.verdict)
      << ", \"error\": " << json_str(c.error) << "}";
  }
  o << "\n  ]\n}\n";
  return o.str();
}

std::string bench_set_json(const std::vector<BenchResult>& r) {
  std::string s = "{\n\"format\": \"ptda-gap-bench-set\",\n\"version\": 1,\n\"corpora\": [\n";
  for (std::size_t i = 0; i < r.size(); ++i) s += (i ? ",\n" : "") + bench_json(r[i]);
  return s + "]\n}\n";
}

std::string bench_markdown(const std::vector<BenchResult>& rs) {
  std::ostringstream o;
  auto pct = [](std::uint32_t a, std::uint32_t b) {
    if (b == 0) return std::string("-");
    char buf[48];
    std::snprintf(buf, sizeof buf, "%u/%u = %.1f %%", a, b, 100.0 * a / b);
    return std::string(buf);
  };
  auto fix = [](double v, const char* unit) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.1f%s", v, unit);
    return std::string(buf);
  };
  o << "| corpus | top-1 | located (of top-1) | named and located (any place in the explanation) | median "
       "held-out shrink | false attr. (controls) | false attr. (out of library) | errors | time per case "
       "(median / max) | CPU per case (max) | peak RSS (max) |\n";
  o << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const BenchResult& r : rs) {
    o << "| " << r.corpus << " | " << pct(r.top1_correct, r.effect_cases) << " | "
      << pct(r.located, r.top1_correct) << " | " << pct(r.named_located, r.effect_cases) << " | "
      << (r.effect_cases ? fix(r.median_shrink_pct, " %") : "-") << " | "
      << pct(r.false_attributions, r.none_cases) << " | " << pct(r.ool_false_attributions, r.ool_cases)
      << " | " << r.errors << " | " << fix(r.median_case_runtime_s, " s") << " / "
      << fix(r.max_case_runtime_s, " s") << " | " << fix(r.max_case_cpu_s, " s") << " | "
      << fix(r.max_peak_rss_mib, " MiB") << " |\n";
  }
  for (const BenchResult& r : rs) {
    o << "\n### " << r.corpus << "\n\nConfusion (rows truth, columns first named):\n\n| truth \\ named |";
    for (std::size_t k = 0; k <= sim::kEffectKinds; ++k) o << " " << short_label(k) << " |";
    o << "\n|---|";
    for (std::size_t k = 0; k <= sim::kEffectKinds; ++k) o << "---|";
    o << "\n";
    for (std::size_t t = 0; t < r.confusion.size(); ++t) {
      std::uint32_t row = 0;
      for (std::uint32_t v : r.confusion[t]) row += v;
      if (row == 0) continue;
      o << "| " << row_label(t) << " |";
      for (std::uint32_t v : r.confusion[t]) o << " " << (v ? std::to_string(v) : "") << " |";
      o << "\n";
    }
    o << "\n| case | truth | named | top-1 | located | shrink | unexplained (probe, share) | time | CPU | "
         "RSS |\n"
         "|---|---|---|---|---|---|---|---|---|---|\n";
    for (const BenchCaseResult& c : r.cases) {
      std::string t = c.description;
      if (t.empty()) {
        for (const EffectSpec& e : c.truth) t += (t.empty() ? "" : " + ") + sim::describe(e);
        if (t.empty()) t = "none";
      }
      std::string n;
      for (const EffectSpec& e : c.chosen) n += (n.empty() ? "" : " + ") + sim::describe(e);
      if (n.empty()) n = c.error.empty() ? "—" : "error: " + c.error;
      o << "| " << c.name << " | " << t << " | " << n << " | " << (c.top1_correct ? "yes" : "**no**") << " | "
        << (c.category == CaseCategory::kEffect ? (c.location_ok ? "yes" : "no") : "") << " | "
        << (c.category == CaseCategory::kEffect ? fix(c.shrink_pct, " %") : "") << " | "
        << (c.remaining_probe.empty() ? "" : c.remaining_probe + " " + fix(100.0 * c.remaining_share, " %"))
        << " | " << fix(c.runtime_s, " s") << " | " << fix(c.cpu_s, " s") << " | "
        << fix(c.peak_rss_mib, " MiB") << " |\n";
    }
  }
  return o.str();
}

}  // namespace ptda::gap
