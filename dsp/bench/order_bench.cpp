// order_bench: time-domain vs order-domain PTDA under speed ripple (issue 16), on synthetic jobs.
// For each ripple level and seed (one seed = one machine): a healthy training job, a fresh healthy job
// and a fresh job with a spur-tooth fault, all with the same speed ripple; both domains are trained on
// the training job and score the other two; the AUC of rms_res (faulty above healthy) and of
// entropy_res (faulty below healthy) is computed per machine. Output: one CSV line per (ripple, seed).
//
//   order_bench --seeds 101-110 --ripples 0,0.01,0.02,0.03,0.04,0.05 [--impulse 0.3] [--am 0.1]
//   order_bench --program short|accel|long ... [--amp-law P] [--speed-law on]
// (--amp-law: the mesh amplitude grows as (speed/f0)^P; --speed-law on: a third arm, "order_law", with the
// trained speed law of dsp::fit_speed_law normalising every window to its class's speed)
//
// Model (all in one place, below): shaft at 25 Hz nominal (joint 4.64 rad/s through a 33.86:1
// cycloidal reduction), plateaus of 2.6 s with speed f0 (1 + ripple sin(2 pi 3 Hz t + psi_c)), 0.2 s
// cosine ramps, 0.3 s standstill; GMF orders 28/56/84 (1, 0.5, 0.25, random phase per cycle), shaft order
// 1, white noise 0.2 rms. Fault: a damped 3 kHz ring (damping 0.05) once per spur-gear revolution (order
// 28/23) of amplitude --impulse, and mesh amplitude modulation by the spur angle of depth --am.
// Time-domain windows: N = 8192 samples (8 revolutions at f0) cut from every plateau after 0.05 s
// whatever the speed tolerance (favours the time domain). Order windows: S = 1024, R = 8.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "order_program.hpp"
#include "ptda/common/error.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/dsp/decision.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/order_windows.hpp"
#include "ptda/dsp/training.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace {

using namespace ptda::dsp;
using namespace ptda::order_bench;

struct Job {
  std::vector<float> x;
  std::vector<SpeedSample> frames;
  std::vector<std::pair<std::size_t, std::size_t>> plateau;
};

Job make_job(std::uint64_t seed, std::uint32_t cycles, double ripple, const Fault& fault) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 2.0 * kPi);
  const double ramp_s = 0.2, plateau_s = 2.6, stand_s = 0.3;
  const double cycle_s = 2.0 * ramp_s + plateau_s + stand_s;
  const auto n_total = static_cast<std::size_t>(cycles * cycle_s * kFs);
  const double w0 = 2.0 * kPi * kF0;
  std::vector<double> psi(cycles), ph1(cycles), ph2(cycles), ph3(cycles);
  for (std::uint32_t c = 0; c < cycles; ++c) {
    psi[c] = uni(rng);
    ph1[c] = uni(rng);
    ph2[c] = uni(rng);
    ph3[c] = uni(rng);
  }
  const auto speed = [&](double t) {
    const auto cyc = std::min<std::uint32_t>(cycles - 1, static_cast<std::uint32_t>(t / cycle_s));
    const double tc = t - cyc * cycle_s;
    if (tc < ramp_s) return w0 * 0.5 * (1.0 - std::cos(kPi * tc / ramp_s));
    if (tc < ramp_s + plateau_s)
      return w0 * (1.0 + ripple * std::sin(2.0 * kPi * 3.0 * (tc - ramp_s) + psi[cyc]));
    if (tc < 2.0 * ramp_s + plateau_s)
      return w0 * 0.5 * (1.0 + std::cos(kPi * (tc - ramp_s - plateau_s) / ramp_s));
    return 0.0;
  };
  ProgJob synth = synthesize_job(speed, n_total, cycles, cycle_s, ph1, ph2, ph3, fault, rng);
  Job job;
  job.x = std::move(synth.x);
  job.frames = std::move(synth.frames);
  for (std::uint32_t c = 0; c < cycles; ++c) {
    const auto b = static_cast<std::size_t>(std::ceil((c * cycle_s + ramp_s + 0.05) * kFs));
    const auto e = std::min(n_total, static_cast<std::size_t>((c * cycle_s + ramp_s + plateau_s) * kFs));
    job.plateau.emplace_back(b, e);
  }
  return job;
}

std::vector<std::vector<float>> time_windows(const Job& job) {
  std::vector<std::vector<float>> w;
  for (const auto& [b, e] : job.plateau)
    for (std::size_t s = b; s + kN <= e; s += kN)
      w.emplace_back(job.x.begin() + static_cast<std::ptrdiff_t>(s),
                     job.x.begin() + static_cast<std::ptrdiff_t>(s + kN));
  return w;
}

std::vector<std::vector<float>> order_windows(const Job& job) {
  AngleResamplerConfig rc;
  rc.samples_per_rev = kS;
  rc.ratio = kRatio;
  AngleResampler res(rc, kFs, kT0);
  OrderWindowCutter cut(OrderWindowConfig{kS, kR, kRatio, res.pass_order()});
  std::vector<std::vector<float>> w;
  std::vector<float> buf(kN);
  OrderWindowRef ref;
  OrderSample o;
  std::size_t f = 0;
  for (std::size_t pos = 0; pos < job.x.size(); pos += 512) {
    const std::size_t m = std::min<std::size_t>(512, job.x.size() - pos);
    const std::int64_t t_end = kT0 + std::llround(static_cast<double>(pos + m) / kFs * 1e9);
    while (f < job.frames.size() && job.frames[f].t_ns < t_end) res.push_speed(job.frames[f++]);
    res.push_samples(std::span<const float>(job.x.data() + pos, m));
    while (res.pop(o)) {
      // The plateau class, a speed band: every sample's shaft speed within 7 % of f0 (the ripple goes
      // up to 5 %), so windows that reach into a ramp are left out, as the time domain's are.
      if (cut.push(o, ref, buf) && ref.min_shaft_speed_rad_s >= 0.93 * 2.0 * kPi * kF0 &&
          ref.max_shaft_speed_rad_s <= 1.07 * 2.0 * kPi * kF0)
        w.push_back(buf);
    }
  }
  return w;
}

ClassBaseline train(const std::vector<std::vector<float>>& w) {
  std::vector<std::uint64_t> groups(w.size());
  for (std::size_t i = 0; i < groups.size(); ++i) groups[i] = i;
  return build_class_baseline(SegmentClass{}, w, groups, ThresholdPolicy{});
}

std::vector<Features> score(const ClassBaseline& c, const std::vector<std::vector<float>>& w) {
  WindowAnalyzer a(kN);
  std::vector<Features> f;
  for (const auto& x : w) f.push_back(a.analyze(x, c, Method::kPtda));
  return f;
}

/// P(faulty > healthy) + P(equal)/2 of the values given by `key`.
template <typename Key>
double auc(const std::vector<Features>& healthy, const std::vector<Features>& faulty, Key key) {
  double s = 0.0;
  for (const Features& f : faulty)
    for (const Features& h : healthy) s += key(f) > key(h) ? 1.0 : (key(f) == key(h) ? 0.5 : 0.0);
  return s / static_cast<double>(healthy.size() * faulty.size());
}

double abnormal(const ClassBaseline& c, const std::vector<Features>& f) {
  const FeatureThresholds& th = c.thresholds[static_cast<std::size_t>(Method::kPtda)];
  std::size_t n = 0;
  for (const Features& x : f)
    if (!th.rms.contains(x.rms_res) || !th.entropy.contains(x.entropy_res)) ++n;
  return static_cast<double>(n) / static_cast<double>(f.size());
}

/// --program short|accel: per seed, domain and severity one CSV line (header in main()).
/// With speed_law, a third arm "order_law": the order domain with the speed law fitted on the
/// training windows (fit_speed_law, one class) and every window normalised with it (stderr: the fit).
/// amp_law: the mesh amplitude's speed exponent of the generator.
void run_program(const std::string& program, std::uint64_t seed_lo, std::uint64_t seed_hi,
                 const std::vector<double>& ripples, const std::vector<double>& severities, const Fault& full,
                 double amp_law, bool speed_law) {
  std::printf(
      "program,ripple,severity,seed,domain,train_windows,healthy_windows,faulty_windows,healthy_coverage,"
      "faulty_coverage,auc_rms,auc_entropy,healthy_abnormal,faulty_abnormal,healthy_alarm,first_abnormal_s,"
      "first_abnormal_window,first_alarm_s,first_alarm_window\n");
  const DecisionConfig dc;  // the product's default k-of-n (3 of 5)
  for (const double ripple : ripples) {
    for (std::uint64_t seed = seed_lo; seed <= seed_hi; ++seed) {
      const ProgJob tr = make_program_job(seed * 1000 + 1, 24, program, ripple, Fault{}, amp_law);
      const ProgJob he = make_program_job(seed * 1000 + 2, 16, program, ripple, Fault{}, amp_law);
      std::vector<ProgJob> fa;
      for (const double sev : severities)
        fa.push_back(make_program_job(seed * 1000 + 3, 16, program, ripple,
                                      Fault{full.impulse * sev, full.am * sev}, amp_law));
      for (int d = 0; d < (speed_law ? 3 : 2); ++d) {
        const char* dom = d == 0 ? "time" : d == 1 ? "order" : "order_law";
        const auto get = [&](const ProgJob& j) { return d == 0 ? time_cut(j) : order_cut(j); };
        Cut trc = get(tr), hec = get(he);
        std::vector<Cut> facs;
        for (const ProgJob& j : fa) facs.push_back(get(j));
        if (d == 2 && !trc.w.empty()) {
          std::vector<Cut*> others{&hec};
          for (Cut& c : facs) others.push_back(&c);
          const SpeedLawFit f = normalise_speed_law(trc, others);
          std::fprintf(stderr,
                       "seed %llu ripple %g: speed law p = %.3f +- %.3f, applied %.3f (%zu windows)\n",
                       static_cast<unsigned long long>(seed), ripple, f.exponent, f.se, f.applied, f.windows);
        }
        bool trained = trc.w.size() >= 3;
        ClassBaseline c;
        if (trained) {
          try {
            c = train(trc.w);
          } catch (const ptda::Error&) {
            trained = false;
          }
        }
        const auto& th = c.thresholds[static_cast<std::size_t>(Method::kPtda)];
        const auto judged = [&](const std::vector<Features>& f, std::vector<bool>& ab) {
          std::size_t n = 0;
          for (const Features& x : f) {
            ab.push_back(judge(x, th).abnormal());
            n += ab.back() ? 1 : 0;
          }
          return f.empty() ? std::nan("") : static_cast<double>(n) / static_cast<double>(f.size());
        };
        std::vector<Features> fh;
        std::vector<bool> abh;
        double h_ab = std::nan("");
        int h_alarm = -1;
        if (trained) {
          fh = score(c, hec.w);
          h_ab = judged(fh, abh);
          KOfNDebouncer deb(dc.k, dc.n);
          h_alarm = 0;
          for (const bool a : abh) h_alarm |= deb.push(a) ? 1 : 0;
        }
        for (std::size_t si = 0; si < severities.size(); ++si) {
          const Cut& fac = facs[si];
          double auc_r = std::nan(""), auc_e = std::nan(""), f_ab = std::nan("");
          double first_ab_s = std::nan(""), first_al_s = std::nan("");
          long first_ab_w = -1, first_al_w = -1;
          if (trained) {
            const auto ff = score(c, fac.w);
            std::vector<bool> abf;
            f_ab = judged(ff, abf);
            if (!fh.empty() && !ff.empty()) {
              auc_r = auc(fh, ff, [](const Features& f) { return f.rms_res; });
              auc_e = auc(fh, ff, [](const Features& f) { return -f.entropy_res; });
            }
            KOfNDebouncer deb(dc.k, dc.n);
            for (std::size_t i = 0; i < abf.size(); ++i) {
              if (abf[i] && first_ab_w < 0) {
                first_ab_w = static_cast<long>(i);
                first_ab_s = fac.t_end_s[i];
              }
              if (deb.push(abf[i]) && first_al_w < 0) {
                first_al_w = static_cast<long>(i);
                first_al_s = fac.t_end_s[i];
              }
            }
          }
          std::printf("%s,%g,%g,%llu,%s,%zu,%zu,%zu,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%d,%.3f,%ld,%.3f,%ld\n",
                      program.c_str(), ripple, severities[si], static_cast<unsigned long long>(seed), dom,
                      trc.w.size(), hec.w.size(), fac.w.size(), hec.judged_s / he.motion_s,
                      fac.judged_s / fa[si].motion_s, auc_r, auc_e, h_ab, f_ab, h_alarm, first_ab_s,
                      first_ab_w, first_al_s, first_al_w);
          std::fflush(stdout);
        }
      }
    }
  }
}

std::vector<double> parse_list(const std::string& s) {
  std::vector<double> v;
  std::size_t p = 0;
  while (p < s.size()) {
    const std::size_t q = s.find(',', p);
    v.push_back(std::stod(s.substr(p, q - p)));
    if (q == std::string::npos) break;
    p = q + 1;
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  std::uint64_t seed_lo = 101, seed_hi = 110;
  std::vector<double> ripples{0.0, 0.01, 0.02, 0.03, 0.04, 0.05};
  Fault fault{0.3, 0.1};
  std::string program = "plateau";
  std::vector<double> severities{1.0};
  double amp_law = 0.0;
  bool speed_law = false;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--seeds") {
      const std::size_t d = v.find('-');
      seed_lo = std::stoull(v.substr(0, d));
      seed_hi = d == std::string::npos ? seed_lo : std::stoull(v.substr(d + 1));
    } else if (k == "--ripples") {
      ripples = parse_list(v);
    } else if (k == "--impulse") {
      fault.impulse = std::stod(v);
    } else if (k == "--program") {
      program = v;
    } else if (k == "--severities") {
      severities = parse_list(v);
    } else if (k == "--am") {
      fault.am = std::stod(v);
    } else if (k == "--amp-law") {
      amp_law = std::stod(v);
    } else if (k == "--speed-law") {
      speed_law = v == "1" || v == "on";
    } else {
      std::fprintf(stderr, "order_bench: unknown option %s\n", k.c_str());
      return 2;
    }
  }
  if (program != "plateau") {
    try {
      run_program(program, seed_lo, seed_hi, ripples, severities, fault, amp_law, speed_law);
    } catch (const ptda::Error& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 2;
    }
    return 0;
  }
  std::printf(
      "ripple,seed,domain,train_windows,healthy_windows,faulty_windows,auc_rms,auc_entropy,"
      "healthy_abnormal,faulty_abnormal,healthy_rms_mean,faulty_rms_mean,healthy_entropy_mean,faulty_entropy_"
      "mean\n");
  for (const double ripple : ripples) {
    for (std::uint64_t seed = seed_lo; seed <= seed_hi; ++seed) {
      const Job tr = make_job(seed * 1000 + 1, 12, ripple, Fault{});
      const Job he = make_job(seed * 1000 + 2, 8, ripple, Fault{});
      const Job fa = make_job(seed * 1000 + 3, 8, ripple, fault);
      for (int d = 0; d < 2; ++d) {
        const auto get = [&](const Job& j) { return d == 0 ? time_windows(j) : order_windows(j); };
        const auto trw = get(tr), hew = get(he), faw = get(fa);
        const ClassBaseline c = train(trw);
        const auto fh = score(c, hew), ff = score(c, faw);
        const auto mean = [](const std::vector<Features>& v, bool rms) {
          double m = 0.0;
          for (const Features& f : v) m += rms ? f.rms_res : f.entropy_res;
          return m / static_cast<double>(v.size());
        };
        std::printf("%g,%llu,%s,%zu,%zu,%zu,%.4f,%.4f,%.4f,%.4f,%.5g,%.5g,%.5g,%.5g\n", ripple,
                    static_cast<unsigned long long>(seed), d == 0 ? "time" : "order", trw.size(), hew.size(),
                    faw.size(), auc(fh, ff, [](const Features& f) { return f.rms_res; }),
                    auc(fh, ff, [](const Features& f) { return -f.entropy_res; }), abnormal(c, fh),
                    abnormal(c, ff), mean(fh, true), mean(ff, true), mean(fh, false), mean(ff, false));
        std::fflush(stdout);
      }
    }
  }
  return 0;
}
