// Order-domain windows and classes (docs/method.md §9).
#include "ptda/dsp/order_windows.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <utility>

#include "number_text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/dsp/real_fft.hpp"

namespace ptda::dsp {

WindowRef window_ref_of(const OrderWindowRef& ref, std::size_t window_len) noexcept {
  WindowRef w;
  w.seq = ref.seq;
  w.region_seq = ref.segment;
  w.index_in_region =
      window_len == 0 ? 0U : static_cast<std::uint32_t>(ref.k_start / static_cast<std::int64_t>(window_len));
  w.first_sample = ref.k_start;
  w.t_start_ns = ref.t_start_ns;
  w.t_end_ns = ref.t_end_ns;
  w.speed_rad_s = ref.joint_speed_rad_s;
  return w;
}

using detail::num;

OrderWindowCutter::OrderWindowCutter(const OrderWindowConfig& cfg) : cfg_(cfg) {
  if (cfg.samples_per_rev == 0 || cfg.revolutions == 0)
    throw Error("order_windows.revolutions and samples_per_rev must be >= 1");
  if (!(cfg.ratio > 0.0) || !std::isfinite(cfg.ratio)) throw Error("order_windows.ratio must be > 0");
  const std::size_t n = static_cast<std::size_t>(cfg.samples_per_rev) * cfg.revolutions;
  if (!RealFft::supported_length(n)) {
    throw Error("order_windows.revolutions: " + std::to_string(cfg.revolutions) + " x " +
                std::to_string(cfg.samples_per_rev) + " samples per revolution = " + std::to_string(n) +
                " is not an FFT length (even, prime factors 2, 3, 5 only)");
  }
  buf_.assign(n, 0.0F);
  if (!(cfg.max_order >= 0.0) || !std::isfinite(cfg.max_order))
    throw Error("order_windows.max_order must be >= 0");
  if (cfg.max_order > 0.0) {
    fft_ = std::make_unique<RealFft>(n);
    spec_.resize(fft_->bins());
    keep_bins_ =
        std::min(spec_.size(), static_cast<std::size_t>(std::floor(cfg.max_order * cfg.revolutions)) + 1);
  }
}

bool OrderWindowCutter::push(const OrderSample& s, OrderWindowRef& ref, std::span<float> out) noexcept {
  const auto n = static_cast<std::int64_t>(buf_.size());
  if (fill_ > 0 && (s.segment != segment_ || s.k != k_start_ + static_cast<std::int64_t>(fill_))) fill_ = 0;
  if (fill_ == 0) {
    if (s.k % n != 0) return false;  // windows start at multiples of N
    k_start_ = s.k;
    t_start_ns_ = s.t_ns;
    segment_ = s.segment;
    direction_ = s.direction;
    min_w_ = max_w_ = s.shaft_speed_rad_s;
  }
  buf_[fill_++] = s.value;
  min_w_ = std::min(min_w_, s.shaft_speed_rad_s);
  max_w_ = std::max(max_w_, s.shaft_speed_rad_s);
  if (fill_ < buf_.size()) return false;
  fill_ = 0;
  if (out.size() != buf_.size()) return false;
  if (fft_) {
    fft_->forward(buf_, spec_);
    std::fill(spec_.begin() + static_cast<std::ptrdiff_t>(keep_bins_), spec_.end(), std::complex<float>{});
    fft_->inverse(spec_, out);
  } else {
    std::copy(buf_.begin(), buf_.end(), out.begin());
  }
  ref.seq = seq_++;
  ref.segment = segment_;
  ref.k_start = k_start_;
  ref.t_start_ns = t_start_ns_;
  ref.t_end_ns = s.t_ns;
  ref.direction = direction_;
  // N - 1 sample steps of 2 pi / S over the time between the first and the last sample.
  const double span_rad = static_cast<double>(n - 1) * 2.0 * std::numbers::pi / cfg_.samples_per_rev;
  const double dt_s = static_cast<double>(s.t_ns - t_start_ns_) * 1e-9;
  ref.shaft_speed_rad_s = dt_s > 0.0 ? span_rad / dt_s : 0.0;
  ref.min_shaft_speed_rad_s = min_w_;
  ref.max_shaft_speed_rad_s = max_w_;
  ref.joint_speed_rad_s = direction_ * ref.shaft_speed_rad_s / cfg_.ratio;
  return true;
}

std::vector<SegmentClass> learn_order_classes_streamed(const SpillVector<OrderWindowRef>& refs,
                                                       double band_rel, std::uint32_t min_segments,
                                                       std::vector<std::string>* dropped) {
  if (!(band_rel > 0.0 && band_rel < 1.0))
    throw Error("order classes: band_rel must be in (0, 1), got " + num(band_rel));
  struct Item {
    double speed;  // |joint speed|
    std::uint64_t segment;
  };
  std::vector<SegmentClass> out;
  for (const std::int8_t dir : {std::int8_t{1}, std::int8_t{-1}}) {
    SpillVector<Item> items(refs.config());
    refs.for_each([&](const OrderWindowRef& r) {
      if ((r.direction < 0 ? -1 : 1) == dir) items.push_back(Item{std::fabs(r.joint_speed_rad_s), r.segment});
    });
    const SpillVector<Item> by_speed =
        sorted(items, [](const Item& a, const Item& b) { return a.speed < b.speed; });
    SpillVector<Item>::Reader rd(by_speed);
    while (!rd.done()) {
      const double anchor = rd.peek().speed;
      double sum = 0.0;
      std::size_t count = 0;
      SpillVector<std::uint64_t> segments(refs.config());
      while (!rd.done() && rd.peek().speed <= anchor * (1.0 + band_rel)) {
        const Item it = rd.next();
        sum += it.speed;
        segments.push_back(it.segment);
        ++count;
      }
      // Distinct segments: the group's segment ids sorted, then counted.
      std::uint32_t distinct = 0;
      {
        bool first = true;
        std::uint64_t prev = 0;
        sorted(segments, std::less<>()).for_each([&](std::uint64_t s) {
          if (first || s != prev) ++distinct;
          first = false;
          prev = s;
        });
      }
      const double mean = sum / static_cast<double>(count);
      if (distinct >= min_segments) {
        SegmentClass c;
        c.direction = dir;
        c.speed_rad_s = mean;
        c.speed_tol_rad_s = 0.5 * band_rel * mean;
        c.regions = distinct;
        out.push_back(c);
      } else if (dropped != nullptr) {
        dropped->push_back("order class " + std::string(dir < 0 ? "-" : "+") + num(mean) +
                           " rad/s: " + std::to_string(distinct) + " segment(s), fewer than " +
                           std::to_string(min_segments));
      }
    }
  }
  for (std::size_t k = 0; k < out.size(); ++k) out[k].id = static_cast<std::uint32_t>(k);
  return out;
}

std::vector<SegmentClass> learn_order_classes(const std::vector<OrderWindowRef>& refs, double band_rel,
                                              std::uint32_t min_segments, std::vector<std::string>* dropped) {
  SpillConfig in_memory;
  in_memory.memory_bytes = std::numeric_limits<std::size_t>::max();  // never spills
  SpillVector<OrderWindowRef> v(in_memory);
  for (const OrderWindowRef& r : refs) v.push_back(r);
  return learn_order_classes_streamed(v, band_rel, min_segments, dropped);
}

OrderTrainingIndex::OrderTrainingIndex(const SpillConfig& cfg)
    : spill(cfg), refs(cfg), recording(cfg), mean_square(cfg) {}

double window_mean_square(std::span<const float> x) noexcept {
  double ss = 0.0;
  for (const float v : x) ss += static_cast<double>(v) * v;
  return x.empty() ? 0.0 : ss / static_cast<double>(x.size());
}

double speed_law_gain(double class_speed_rad_s, double speed_rad_s, double exponent) noexcept {
  const double v = std::fabs(speed_rad_s);
  if (exponent == 0.0 || !(v > 0.0) || !(class_speed_rad_s > 0.0)) return 1.0;
  return std::pow(class_speed_rad_s / v, exponent);
}

namespace {
/// A training window belongs to a class: its direction, and its speed within the class's band.
bool in_class(const OrderWindowRef& r, const SegmentClass& c) {
  return (r.direction < 0 ? -1 : 1) == c.direction &&
         std::fabs(std::fabs(r.joint_speed_rad_s) - c.speed_rad_s) <= c.speed_tol_rad_s;
}
/// The first class a window belongs to, or -1.
int class_of(const OrderWindowRef& r, const std::vector<SegmentClass>& classes) {
  for (std::size_t k = 0; k < classes.size(); ++k)
    if (in_class(r, classes[k])) return static_cast<int>(k);
  return -1;
}
}  // namespace

SpeedLawFit fit_speed_law_streamed(const SpillVector<OrderWindowRef>& refs,
                                   const SpillVector<double>& mean_square,
                                   const std::vector<SegmentClass>& classes) {
  // y = ln RMS, x = ln |v|; per class the means are removed (each class has its own level), one slope.
  struct Acc {
    double n = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, sxy = 0.0, syy = 0.0;
  };
  std::vector<Acc> acc(classes.size());
  SpeedLawFit f;
  SpillVector<OrderWindowRef>::Reader rr(refs);
  SpillVector<double>::Reader mr(mean_square);
  while (!rr.done() && !mr.done()) {
    const OrderWindowRef r = rr.next();
    const double ms = mr.next();
    const int k = class_of(r, classes);
    const double v = std::fabs(r.joint_speed_rad_s);
    if (k < 0 || !(v > 0.0)) continue;
    if (!(ms > 0.0) || !std::isfinite(ms)) continue;
    const double x = std::log(v), y = 0.5 * std::log(ms);
    Acc& a = acc[static_cast<std::size_t>(k)];
    a.n += 1.0;
    a.sx += x;
    a.sy += y;
    a.sxx += x * x;
    a.sxy += x * y;
    a.syy += y * y;
    ++f.windows;
  }
  double sxx = 0.0, sxy = 0.0, syy = 0.0, groups = 0.0, n = 0.0;
  for (const Acc& a : acc) {
    if (a.n < 1.0) continue;
    groups += 1.0;
    n += a.n;
    sxx += a.sxx - a.sx * a.sx / a.n;
    sxy += a.sxy - a.sx * a.sy / a.n;
    syy += a.syy - a.sy * a.sy / a.n;
  }
  const double dof = n - groups - 1.0;
  if (!(sxx > 1e-12) || dof < 3.0) return f;
  f.exponent = sxy / sxx;
  const double rss = std::max(0.0, syy - f.exponent * sxy);
  f.se = std::sqrt(rss / dof / sxx);
  // Applied when significant; an exponent beyond 8 is no physical speed law (the file format's bound).
  f.applied = std::fabs(f.exponent) > 2.0 * f.se && std::fabs(f.exponent) <= 8.0 ? f.exponent : 0.0;
  return f;
}

SpeedLawFit fit_speed_law(const std::vector<OrderWindowRef>& refs,
                          const std::vector<std::vector<float>>& windows,
                          const std::vector<SegmentClass>& classes) {
  SpillConfig in_memory;
  in_memory.memory_bytes = std::numeric_limits<std::size_t>::max();
  SpillVector<OrderWindowRef> r(in_memory);
  SpillVector<double> ms(in_memory);
  for (std::size_t i = 0; i < refs.size() && i < windows.size(); ++i) {
    if (windows[i].empty()) continue;  // no samples: no mean square
    r.push_back(refs[i]);
    ms.push_back(window_mean_square(windows[i]));
  }
  return fit_speed_law_streamed(r, ms, classes);
}

Baseline train_order_baseline(const OrderWindows& data, const OrderWindowConfig& cfg, double band_rel,
                              const ThresholdPolicy& policy, const GearboxInfo& gearbox,
                              std::vector<std::string>* dropped, bool learn_speed_law,
                              std::uint32_t min_segments) {
  if (data.refs.size() != data.windows.size())
    throw Error("train_order_baseline: " + std::to_string(data.refs.size()) + " refs but " +
                std::to_string(data.windows.size()) + " windows");
  OrderTrainingIndex index;
  for (std::size_t i = 0; i < data.refs.size(); ++i) {
    index.refs.push_back(data.refs[i]);
    index.recording.push_back(data.recording.empty() ? 0U : data.recording[i]);
    index.mean_square.push_back(window_mean_square(data.windows[i]));
  }
  const TrainingWindowPass pass = [&data](const TrainingWindowVisitor& visit) {
    for (std::size_t i = 0; i < data.windows.size(); ++i) visit(i, data.windows[i]);
  };
  return train_order_baseline_streamed(index, pass, cfg, band_rel, policy, gearbox, dropped, learn_speed_law,
                                       min_segments);
}

Baseline train_order_baseline_streamed(const OrderTrainingIndex& data, const TrainingWindowPass& pass,
                                       const OrderWindowConfig& cfg, double band_rel,
                                       const ThresholdPolicy& policy, const GearboxInfo& gearbox,
                                       std::vector<std::string>* dropped, bool learn_speed_law,
                                       std::uint32_t min_segments) {
  if (data.recording.size() != data.refs.size() || data.mean_square.size() != data.refs.size()) {
    throw Error("train_order_baseline: " + std::to_string(data.refs.size()) + " refs but " +
                std::to_string(data.recording.size()) + " recording ids and " +
                std::to_string(data.mean_square.size()) + " mean squares");
  }
  const std::size_t count = data.refs.size();
  const std::size_t n = static_cast<std::size_t>(cfg.samples_per_rev) * cfg.revolutions;
  std::vector<std::string> why;
  Baseline b;
  b.fs_hz = cfg.samples_per_rev;
  b.window_len = static_cast<std::uint32_t>(n);
  b.gearbox = gearbox;
  b.policy = policy;
  const std::vector<SegmentClass> classes =
      learn_order_classes_streamed(data.refs, band_rel, std::max<std::uint32_t>(1, min_segments), &why);
  if (learn_speed_law) {
    const SpeedLawFit law = fit_speed_law_streamed(data.refs, data.mean_square, classes);
    b.speed_law_fit = law.exponent;
    b.speed_law_se = law.se;
    b.speed_law_exponent = law.applied;
  }
  // Each class with >= 3 windows gets a builder; a window may fall in more than one class's band.
  std::vector<std::size_t> members(classes.size(), 0);
  data.refs.for_each([&](const OrderWindowRef& r) {
    for (std::size_t k = 0; k < classes.size(); ++k) members[k] += in_class(r, classes[k]) ? 1 : 0;
  });
  std::vector<std::optional<ClassBaselineBuilder>> builders(classes.size());
  for (std::size_t k = 0; k < classes.size(); ++k) {
    if (members[k] < 3) continue;
    builders[k].emplace(classes[k], n, policy, data.spill);
  }
  std::size_t expected = 0;
  const auto check = [&](std::size_t i, const char* what) {
    if (i != expected) {
      throw Error(std::string("train_order_baseline: ") + what + " handed over window " + std::to_string(i) +
                  " where window " + std::to_string(expected) +
                  " was expected (the windows changed between passes)");
    }
    ++expected;
  };
  const auto check_complete = [&](const char* what) {
    if (expected != count) {
      throw Error(std::string("train_order_baseline: ") + what + " handed over " + std::to_string(expected) +
                  " of " + std::to_string(count) + " windows (the windows changed between passes)");
    }
  };
  // A class's copy of a window, normalised to the class's speed by the speed law when it is applied.
  std::vector<float> scaled(n);
  const auto class_window = [&](const OrderWindowRef& r, const SegmentClass& c,
                                std::span<const float> x) -> std::span<const float> {
    if (b.speed_law_exponent == 0.0) return x;
    const auto g =
        static_cast<float>(speed_law_gain(c.speed_rad_s, r.joint_speed_rad_s, b.speed_law_exponent));
    scaled.assign(x.begin(), x.end());
    for (float& v : scaled) v *= g;
    return scaled;
  };
  {
    SpillVector<OrderWindowRef>::Reader refs(data.refs);
    pass([&](std::size_t i, std::span<const float> x) {
      check(i, "pass 1");
      const OrderWindowRef r = refs.next();
      for (std::size_t k = 0; k < classes.size(); ++k) {
        if (builders[k] && in_class(r, classes[k])) builders[k]->add_to_mean(class_window(r, classes[k], x));
      }
    });
  }
  check_complete("pass 1");
  for (auto& bld : builders) {
    if (bld) bld->finish_mean();
  }
  // Pass 2: non-overlapping windows, each its own leave-out group, scored in cut order (= seq order).
  expected = 0;
  {
    SpillVector<OrderWindowRef>::Reader refs(data.refs);
    SpillVector<std::uint32_t>::Reader recs(data.recording);
    pass([&](std::size_t i, std::span<const float> x) {
      check(i, "pass 2");
      const OrderWindowRef r = refs.next();
      const std::uint32_t rec = recs.next();
      for (std::size_t k = 0; k < classes.size(); ++k) {
        if (!builders[k] || !in_class(r, classes[k])) continue;
        const std::span<const float> w = class_window(r, classes[k], x);
        const std::span<const float> one[1] = {w};
        const std::uint32_t one_rec[1] = {rec};
        builders[k]->score_group(one, one_rec);
      }
    });
  }
  check_complete("pass 2");
  for (std::size_t k = 0; k < classes.size(); ++k) {
    if (!builders[k]) {
      why.push_back("order class " + num(classes[k].speed_rad_s) + " rad/s: " + std::to_string(members[k]) +
                    " window(s) within its band, fewer than 3");
      continue;
    }
    ClassBaseline cb = builders[k]->finish();
    cb.segment.id = static_cast<std::uint32_t>(b.classes.size());
    b.classes.push_back(std::move(cb));
  }
  if (dropped != nullptr) dropped->insert(dropped->end(), why.begin(), why.end());
  if (b.classes.empty()) {
    std::string msg =
        "train_order_baseline: no order class has enough windows (" + std::to_string(count) + " windows)";
    for (const std::string& w : why) msg += "; " + w;
    throw Error(msg);
  }
  return b;
}

}  // namespace ptda::dsp
