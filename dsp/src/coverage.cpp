// CoverageTracker: fixed-size counting of judged and unjudged windows and of motion time.
#include "ptda/dsp/coverage.hpp"

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <string>

#include "ptda/common/error.hpp"

namespace ptda::dsp {

namespace {

/// Appends printf-formatted text to a fixed buffer only when all of it fits (so a multi-byte character
/// is never cut); returns false when it did not fit.
class Line {
 public:
  Line(char* out, std::size_t size) noexcept : out_(out), size_(size) {
    if (size_ > 0) out_[0] = '\0';
  }
  /// printf-style; the format attribute lets the compiler check every call's literal format.
  __attribute__((format(printf, 2, 3))) bool add(const char* fmt, ...) noexcept {
    if (full_ || size_ == 0) return false;
    char tmp[128];
    std::va_list ap;
    va_start(ap, fmt);
    const int n = std::vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    if (n < 0 || static_cast<std::size_t>(n) >= sizeof tmp || len_ + static_cast<std::size_t>(n) >= size_) {
      full_ = true;
      return false;
    }
    for (int i = 0; i <= n; ++i) out_[len_ + static_cast<std::size_t>(i)] = tmp[i];
    len_ += static_cast<std::size_t>(n);
    return true;
  }
  [[nodiscard]] std::size_t len() const noexcept { return len_; }

 private:
  char* out_;
  std::size_t size_;
  std::size_t len_ = 0;
  bool full_ = false;
};

// "trained ±1.05, +2.10": one item per distinct speed, ± when both directions have it.
void add_trained(Line& line, const Baseline& b) noexcept {
  line.add("trained");
  bool first = true;
  for (std::size_t i = 0; i < b.classes.size(); ++i) {
    const SegmentClass& c = b.classes[i].segment;
    bool dup = false;    // the same speed listed already (the other direction)
    bool other = false;  // the other direction exists at this speed
    for (std::size_t j = 0; j < b.classes.size(); ++j) {
      const SegmentClass& d = b.classes[j].segment;
      if (j == i || std::fabs(d.speed_rad_s - c.speed_rad_s) > 0.005) continue;
      if (d.direction != c.direction) other = true;
      if (j < i) dup = true;
    }
    if (dup) continue;
    const char* sign = other ? "\u00b1" : (c.direction < 0 ? "-" : "+");
    if (!line.add(first ? " %s%.2f" : ", %s%.2f", sign, c.speed_rad_s)) {
      line.add(", ...");
      return;
    }
    first = false;
  }
}

}  // namespace

std::size_t describe_coverage(const CoverageState& st, const Baseline& baseline, double timeout_s, char* out,
                              std::size_t out_size) noexcept {
  Line line(out, out_size);
  switch (st.level) {
    case CoverageLevel::kFull:
      break;
    case CoverageLevel::kWaiting:
      line.add("not judged yet");
      break;
    case CoverageLevel::kPartial: {
      line.add("partial coverage:");
      bool first = true;
      const std::size_t n = st.class_count < kCoverageMaxClasses ? st.class_count : kCoverageMaxClasses;
      for (std::size_t i = 0; i < n && i < baseline.classes.size(); ++i) {
        if (st.class_current(static_cast<std::uint32_t>(i), timeout_s)) continue;
        const SegmentClass& c = baseline.classes[i].segment;
        const double blind_s = static_cast<double>(st.moving_ns - st.classes[i].moving_at_last_ns) * 1e-9;
        if (!line.add(st.classes[i].have ? "%s class %u (%c%.2f rad/s) not judged for %.0f s of motion"
                                         : "%s class %u (%c%.2f rad/s) never judged in %.0f s of motion",
                      first ? "" : ",", static_cast<unsigned>(c.id), c.direction < 0 ? '-' : '+',
                      c.speed_rad_s, blind_s)) {
          line.add(", ...");
          break;
        }
        first = false;
      }
      break;
    }
    case CoverageLevel::kNotJudging: {
      line.add("not judging: ");
      // Unmatched speeds seen since the last judgement (all of them before the first one).
      bool any_speed = false;
      for (std::uint32_t i = 0; i < st.speed_bins; ++i) {
        if (!st.have_judged || st.speeds[i].last_t_ns > st.last_judged_t_ns) any_speed = true;
      }
      const bool invalid = st.unmatched[static_cast<std::size_t>(UnmatchedReason::kInvalid)] > 0 &&
                           (!st.have_judged || st.last_invalid_t_ns > st.last_judged_t_ns);
      if (any_speed) {
        line.add("no window matches a trained class (seen");
        bool first = true;
        for (std::uint32_t i = 0; i < st.speed_bins; ++i) {
          const UnmatchedSpeed& b = st.speeds[i];
          if (st.have_judged && b.last_t_ns <= st.last_judged_t_ns) continue;
          if (!line.add(first ? " %.2f" : ", %.2f", b.speed_rad_s)) break;
          first = false;
        }
        line.add(" rad/s; ");
        add_trained(line, baseline);
        line.add(")");
        if (invalid) line.add("; windows with invalid samples discarded");
      } else if (invalid) {
        line.add("every window cut was discarded (invalid samples) for %.0f s of motion",
                 st.moving_since_judged_s());
      } else {
        line.add("no constant-speed window for %.0f s of motion (", st.moving_since_judged_s());
        add_trained(line, baseline);
        line.add(")");
      }
      break;
    }
  }
  return line.len();
}

CoverageTracker::CoverageTracker(const Baseline& baseline, const CoverageConfig& cfg) : cfg_(cfg) {
  // 1e6 s keeps the ns value far from int64 overflow.
  if (!(std::isfinite(cfg.timeout_s) && cfg.timeout_s > 0.0 && cfg.timeout_s <= 1e6)) {
    throw Error("coverage_timeout_s: must be a finite number of seconds in (0, 1e6], got " +
                std::to_string(cfg.timeout_s));
  }
  timeout_ns_ = std::llround(cfg.timeout_s * 1e9);
  max_gap_ns_ = std::llround(cfg.max_speed_gap_s * 1e9);
  for (const ClassBaseline& c : baseline.classes) {
    if (c.segment.direction < 0) {
      has_backward_ = true;
    } else {
      has_forward_ = true;
    }
  }
  st_.class_count = static_cast<std::uint32_t>(baseline.classes.size());
}

void CoverageTracker::see_time(std::int64_t t_ns) noexcept {
  if (!st_.have_time) {
    st_.have_time = true;
    st_.first_t_ns = t_ns;
    st_.latest_t_ns = t_ns;
  } else if (t_ns > st_.latest_t_ns) {
    st_.latest_t_ns = t_ns;
  }
}

void CoverageTracker::on_speed(const SpeedSample& s) noexcept {
  see_time(s.t_ns);
  const bool moving = std::fabs(s.speed_rad_s) >= cfg_.moving_speed_rad_s;
  if (have_speed_ && moving && std::fabs(last_speed_.speed_rad_s) >= cfg_.moving_speed_rad_s) {
    const std::int64_t dt = s.t_ns - last_speed_.t_ns;
    if (dt > 0 && dt <= max_gap_ns_) st_.moving_ns += dt;
  }
  if (!have_speed_ || s.t_ns > last_speed_.t_ns) {  // out-of-order samples do not move the reference
    last_speed_ = s;
    have_speed_ = true;
    marks_[marks_pushed_ & (kMotionMarks - 1)] = MotionMark{s.t_ns, st_.moving_ns};
    ++marks_pushed_;
  }
  update_level();
}

std::int64_t CoverageTracker::moving_at(std::int64_t t_ns) const noexcept {
  if (marks_pushed_ == 0) return st_.moving_ns;
  const std::uint64_t first = marks_pushed_ > kMotionMarks ? marks_pushed_ - kMotionMarks : 0;
  const auto at = [&](std::uint64_t i) -> const MotionMark& { return marks_[i & (kMotionMarks - 1)]; };
  if (t_ns >= at(marks_pushed_ - 1).t_ns) return st_.moving_ns;
  if (t_ns <= at(first).t_ns) return at(first).moving_ns;
  // Marks are in time order: the last one at or before t_ns.
  std::uint64_t lo = first, hi = marks_pushed_ - 1;  // at(lo).t <= t < at(hi).t
  while (hi - lo > 1) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    if (at(mid).t_ns <= t_ns) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  const MotionMark& a = at(lo);
  const MotionMark& b = at(hi);
  // Motion between two samples accrues evenly over their step (or not at all).
  const double f = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  return a.moving_ns +
         static_cast<std::int64_t>(std::llround(f * static_cast<double>(b.moving_ns - a.moving_ns)));
}

void CoverageTracker::on_window(const WindowResult& w) noexcept {
  see_time(w.ref.t_end_ns);
  if (w.status == WindowStatus::kScored) {
    ++st_.judged;
    st_.have_judged = true;
    st_.last_judged_t_ns = w.ref.t_end_ns;
    const std::int64_t moving_then = moving_at(w.ref.t_end_ns);
    if (moving_then > st_.moving_at_last_judged_ns) st_.moving_at_last_judged_ns = moving_then;
    if (w.class_id >= 0 && static_cast<std::size_t>(w.class_id) < kCoverageMaxClasses) {
      ClassCoverage& c = st_.classes[static_cast<std::size_t>(w.class_id)];
      ++c.judged;
      c.have = true;
      c.last_t_ns = w.ref.t_end_ns;
      if (moving_then > c.moving_at_last_ns) c.moving_at_last_ns = moving_then;
    }
  } else {
    const bool forward = w.ref.speed_rad_s >= 0.0;
    const UnmatchedReason reason =
        (forward ? has_forward_ : has_backward_) ? UnmatchedReason::kSpeed : UnmatchedReason::kDirection;
    ++st_.unmatched[static_cast<std::size_t>(reason)];
    const double v = w.ref.speed_rad_s;
    bool binned = false;
    for (std::uint32_t i = 0; i < st_.speed_bins && !binned; ++i) {
      UnmatchedSpeed& b = st_.speeds[i];
      const double tol = std::fmax(0.02 * std::fabs(b.speed_rad_s), 0.01);
      if ((b.speed_rad_s < 0.0) == (v < 0.0) && std::fabs(v - b.speed_rad_s) <= tol) {
        ++b.count;
        b.speed_rad_s += (v - b.speed_rad_s) / static_cast<double>(b.count);
        b.last_t_ns = w.ref.t_end_ns;
        binned = true;
      }
    }
    if (!binned && st_.speed_bins < kCoverageSpeedBins) {
      st_.speeds[st_.speed_bins++] = UnmatchedSpeed{v, 1, w.ref.t_end_ns};
      binned = true;
    }
    if (!binned) ++st_.speeds_not_binned;
  }
  update_level();
}

void CoverageTracker::on_discarded_total(std::uint64_t discarded_total) noexcept {
  if (discarded_total > discarded_seen_) {
    st_.unmatched[static_cast<std::size_t>(UnmatchedReason::kInvalid)] += discarded_total - discarded_seen_;
    st_.last_invalid_t_ns = st_.latest_t_ns;
    discarded_seen_ = discarded_total;
  }
}

void CoverageTracker::finish() noexcept {
  st_.finished = true;
  update_level();
}

void CoverageTracker::update_level() noexcept {
  const std::int64_t blind = st_.moving_ns - st_.moving_at_last_judged_ns;
  if (blind >= timeout_ns_ || (st_.finished && !st_.have_judged && st_.moving_ns > 0)) {
    st_.level = CoverageLevel::kNotJudging;
  } else if (!st_.have_judged) {
    st_.level = CoverageLevel::kWaiting;
  } else {
    bool all = true;
    const std::size_t n = st_.class_count < kCoverageMaxClasses ? st_.class_count : kCoverageMaxClasses;
    for (std::size_t i = 0; i < n && all; ++i)
      all = st_.class_current(static_cast<std::uint32_t>(i), cfg_.timeout_s);
    st_.level = all ? CoverageLevel::kFull : CoverageLevel::kPartial;
  }
}

}  // namespace ptda::dsp
