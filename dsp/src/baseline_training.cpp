// The training glue: segment classes from the regions of a healthy recording, then the baseline from
// its collected windows (build_class_baseline() per class). Offline code (and the daemon's training
// mode): allocates and throws ptda::Error. See docs/windows.md.
#include "ptda/dsp/baseline_training.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "number_text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/decision.hpp"
#include "ptda/dsp/mesh_modulation.hpp"

namespace ptda::dsp {
namespace {

using detail::num;

}  // namespace

std::vector<SegmentClass> learn_segment_classes(const std::vector<RegionInfo>& regions,
                                                const ClassLearningConfig& cfg,
                                                std::vector<std::string>* dropped) {
  if (!(std::isfinite(cfg.speed_tol_rel) && cfg.speed_tol_rel >= 0.0)) {
    throw Error("classes.speed_tol_rel: must be finite and >= 0, got " + num(cfg.speed_tol_rel));
  }
  if (!(std::isfinite(cfg.speed_tol_abs_rad_s) && cfg.speed_tol_abs_rad_s >= 0.0)) {
    throw Error("classes.speed_tol_abs_rad_s: must be finite and >= 0, got " + num(cfg.speed_tol_abs_rad_s));
  }
  if (cfg.min_regions == 0) throw Error("classes.min_regions: must be >= 1");
  const auto tol_at = [&](double speed) {
    return std::max(cfg.speed_tol_rel * speed, cfg.speed_tol_abs_rad_s);
  };

  struct Item {
    double speed;  // |mean speed|
    double duration_s;
  };
  std::vector<SegmentClass> out;
  for (const std::int8_t dir : {std::int8_t{1}, std::int8_t{-1}}) {  // forward classes first
    std::vector<Item> items;
    for (const RegionInfo& r : regions) {
      if ((r.direction < 0 ? -1 : 1) != dir) continue;
      if (!std::isfinite(r.mean_speed_rad_s))
        throw Error("learn_segment_classes: region " + std::to_string(r.seq) +
                    " has a non-finite mean speed");
      items.push_back(
          Item{std::fabs(r.mean_speed_rad_s), static_cast<double>(r.t_end_ns - r.t_begin_ns) * 1e-9});
    }
    std::stable_sort(items.begin(), items.end(),
                     [](const Item& a, const Item& b) { return a.speed < b.speed; });
    // Greedy: a group is anchored at its slowest region and takes every region within the anchor's
    // tolerance. Every member is then within the class tolerance of the class mean (the mean is at
    // or above the anchor, so its tolerance is at least the anchor's), so training regions always
    // match their own class.
    std::size_t i = 0;
    while (i < items.size()) {
      const double anchor = items[i].speed;
      std::size_t j = i;
      double sum = 0.0;
      std::vector<double> durations;
      while (j < items.size() && items[j].speed - anchor <= tol_at(anchor)) {
        sum += items[j].speed;
        durations.push_back(items[j].duration_s);
        ++j;
      }
      if (durations.size() >= cfg.min_regions) {
        std::sort(durations.begin(), durations.end());
        const std::size_t m = durations.size();
        SegmentClass c;
        c.direction = dir;
        c.speed_rad_s = sum / static_cast<double>(m);
        c.speed_tol_rad_s = tol_at(c.speed_rad_s);
        c.duration_s = m % 2 == 1 ? durations[m / 2] : 0.5 * (durations[m / 2 - 1] + durations[m / 2]);
        c.regions = static_cast<std::uint32_t>(m);
        out.push_back(c);
      } else if (dropped != nullptr) {
        dropped->push_back("speed " + std::string(dir < 0 ? "-" : "+") +
                           num(sum / static_cast<double>(j - i)) + " rad/s: " + std::to_string(j - i) +
                           " region(s), fewer than classes.min_regions = " + std::to_string(cfg.min_regions));
      }
      i = j;
    }
  }
  for (std::size_t k = 0; k < out.size(); ++k) out[k].id = static_cast<std::uint32_t>(k);
  return out;
}

Baseline train_baseline(const CollectedWindows& data, const ClassLearningConfig& classes,
                        const ThresholdPolicy& policy, double fs_hz, const GearboxInfo& gearbox,
                        std::vector<std::string>* dropped) {
  if (data.refs.size() != data.windows.size()) {
    throw Error("train_baseline: " + std::to_string(data.refs.size()) + " window refs but " +
                std::to_string(data.windows.size()) + " windows");
  }
  const std::size_t n = data.windows.empty() ? 0 : data.windows.front().size();
  for (std::size_t i = 0; i < data.windows.size(); ++i) {
    if (data.windows[i].size() != n) {
      throw Error("train_baseline: window " + std::to_string(i) + " has " +
                  std::to_string(data.windows[i].size()) + " samples, the first has " + std::to_string(n));
    }
  }
  const TrainingWindowPass pass = [&data](const TrainingWindowVisitor& visit) {
    for (std::size_t i = 0; i < data.windows.size(); ++i) visit(i, data.windows[i]);
  };
  return train_baseline_streamed(data, n, pass, classes, policy, fs_hz, gearbox, dropped);
}

Baseline train_baseline_streamed(const CollectedWindows& data, std::size_t n, const TrainingWindowPass& pass,
                                 const ClassLearningConfig& classes, const ThresholdPolicy& policy,
                                 double fs_hz, const GearboxInfo& gearbox,
                                 std::vector<std::string>* dropped) {
  if (!(policy.holdout_fraction >= 0.0 && policy.holdout_fraction <= 0.9)) {
    throw Error("thresholds.holdout_fraction: must be in [0, 0.9], got " + num(policy.holdout_fraction));
  }
  if (policy.mesh_stats && (gearbox.z_in == 0 || !(gearbox.ratio > 0.0))) {
    throw Error(
        "train_baseline: [decision] mesh_cusum needs the gearbox's input pinion teeth and ratio "
        "([gearbox] z_in, z_spur, z_pin or ratio); this gearbox has z_in = " +
        std::to_string(gearbox.z_in) + ", ratio = " + num(gearbox.ratio));
  }
  if (!data.recording.empty() && data.recording.size() != data.refs.size()) {
    throw Error("train_baseline: " + std::to_string(data.recording.size()) + " recording ids but " +
                std::to_string(data.refs.size()) + " windows");
  }
  if (data.refs.empty()) {
    throw Error("train_baseline: no constant-speed windows in the training data (" +
                std::to_string(data.regions.size()) + " regions found)");
  }

  // Why each speed group or class is left out, for the caller and for the error below.
  std::vector<std::string> why;
  Baseline candidates;
  for (const SegmentClass& c : learn_segment_classes(data.regions, classes, &why)) {
    ClassBaseline cb;
    cb.segment = c;
    candidates.classes.push_back(std::move(cb));
  }

  // Overlap groups: windows of one region whose sample ranges overlap (directly or through a chain)
  // share a group, so leave-one-group-out never scores a window against a mean containing its own
  // samples; disjoint windows of one long region are separate groups.
  std::vector<std::uint64_t> group(data.refs.size(), 0);
  {
    std::vector<std::size_t> order(data.refs.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      const WindowRef& p = data.refs[a];
      const WindowRef& q = data.refs[b];
      return p.region_seq != q.region_seq ? p.region_seq < q.region_seq : p.first_sample < q.first_sample;
    });
    std::uint64_t next_group = 0;
    std::int64_t reach = 0;  // end (exclusive) of the current group's samples
    for (std::size_t k = 0; k < order.size(); ++k) {
      const WindowRef& r = data.refs[order[k]];
      const bool same_region = k > 0 && data.refs[order[k - 1]].region_seq == r.region_seq;
      if (!(same_region && r.first_sample < reach)) {
        ++next_group;
        reach = r.first_sample;
      }
      reach = std::max(reach, r.first_sample + static_cast<std::int64_t>(n));
      group[order[k]] = next_group - 1;
    }
  }

  struct Members {
    std::vector<std::size_t> windows;
    std::vector<std::uint64_t> groups;
  };
  std::vector<Members> members(candidates.classes.size());
  std::size_t unmatched = 0;
  for (std::size_t i = 0; i < data.refs.size(); ++i) {
    const ClassBaseline* c = candidates.match(data.refs[i].speed_rad_s);
    if (c == nullptr) {
      ++unmatched;
      continue;
    }
    Members& m = members[static_cast<std::size_t>(c - candidates.classes.data())];
    m.windows.push_back(i);
    m.groups.push_back(group[i]);
  }

  // Operating time of the training data: the time from each window's start to the next one's (in cut
  // order), a pause longer than 10 median intervals (another recording, a program stop) counting as
  // one median interval; the last window adds one median interval.
  double hours = 0.0;
  {
    std::vector<double> dt_s;
    for (std::size_t i = 1; i < data.refs.size(); ++i) {
      const double d = static_cast<double>(data.refs[i].t_start_ns - data.refs[i - 1].t_start_ns) * 1e-9;
      if (d > 0.0) dt_s.push_back(d);
    }
    if (!dt_s.empty()) {
      std::vector<double> sorted = dt_s;
      std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                       sorted.end());
      const double median = sorted[sorted.size() / 2];
      double total = median;
      for (std::size_t i = 1; i < data.refs.size(); ++i) {
        const double d = static_cast<double>(data.refs[i].t_start_ns - data.refs[i - 1].t_start_ns) * 1e-9;
        total += (d > 0.0 && d <= 10.0 * median) ? d : median;
      }
      hours = total / 3600.0;
    }
  }

  Baseline out;
  out.fs_hz = fs_hz;
  out.window_len = static_cast<std::uint32_t>(n);
  out.gearbox = gearbox;
  out.policy = policy;
  std::string summary;
  // What each kept class needs from the passes: its fit windows' groups (in order, with their sizes) and
  // its held-out windows' features.
  struct Plan {
    ClassBaselineBuilder builder;
    // Fit groups, ascending, and their window counts (a vector: 12 bytes a group, where a map node
    // took about 64; one window per group is common).
    std::vector<std::pair<std::uint64_t, std::uint32_t>> group_size;
    std::map<std::uint64_t, std::vector<std::pair<std::vector<float>, std::uint32_t>>> pending;
    std::size_t next_group = 0;
    std::vector<std::array<Features, kMethodCount>> held;  // features of the held-out windows, in cut order
    std::size_t held_windows = 0;
    std::size_t class_windows = 0;  // windows matching the class (fit and held out)
    // Mesh detector (policy.mesh_stats): the class's demodulator and its fit windows' am, pm values.
    std::optional<MeshDemodulator> mesh;
    std::array<std::vector<double>, kMeshFeatureCount> mesh_values;
    std::array<std::vector<std::uint32_t>, kMeshFeatureCount> mesh_recording;
  };
  std::vector<Plan> plans;
  constexpr std::int32_t kNoClass = -1;
  std::vector<std::int32_t> plan_of(data.refs.size(), kNoClass);  // the window's plan, when it has one
  std::vector<bool> is_held(data.refs.size(), false);
  for (std::size_t k = 0; k < candidates.classes.size(); ++k) {
    const SegmentClass& seg = candidates.classes[k].segment;
    std::vector<std::uint64_t> distinct = members[k].groups;
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    summary += "; class " + std::to_string(seg.id) + " (" + (seg.direction < 0 ? "-" : "+") +
               num(seg.speed_rad_s) + " rad/s): " + std::to_string(seg.regions) + " regions, " +
               std::to_string(members[k].windows.size()) + " windows in " + std::to_string(distinct.size()) +
               " non-overlapping groups";
    if (distinct.size() < 3) {
      why.push_back(
          "speed " + std::string(seg.direction < 0 ? "-" : "+") + num(seg.speed_rad_s) +
          " rad/s: " + std::to_string(seg.regions) + " regions but its " +
          std::to_string(members[k].windows.size()) + " windows fall in " + std::to_string(distinct.size()) +
          " non-overlapping group(s), leave-one-group-out needs >= 3 (longer regions or more cycles)");
      continue;
    }
    // Hold-out: the latest groups (group ids follow cut order), never fewer than 3 groups left to fit.
    const std::size_t n_hold = std::min(
        static_cast<std::size_t>(std::floor(policy.holdout_fraction * static_cast<double>(distinct.size()))),
        distinct.size() - 3);
    const std::uint64_t first_held = n_hold == 0 ? ~std::uint64_t{0} : distinct[distinct.size() - n_hold];
    SegmentClass renumbered = seg;
    renumbered.id = static_cast<std::uint32_t>(plans.size());
    Plan plan{ClassBaselineBuilder(renumbered, n, policy), {}, {}, 0, {}, 0, 0, {}, {}, {}};
    for (std::size_t j = 0; j < members[k].windows.size(); ++j) {
      const std::size_t i = members[k].windows[j];
      plan_of[i] = static_cast<std::int32_t>(plans.size());
      const std::uint64_t g = members[k].groups[j];
      if (g >= first_held) {
        is_held[i] = true;
        ++plan.held_windows;
      } else if (!plan.group_size.empty() && plan.group_size.back().first == g) {
        ++plan.group_size.back().second;  // a group's windows come in a run (cut order)
      } else {
        plan.group_size.emplace_back(g, 1U);
      }
    }
    // Cut order is group order within a recording; sort (stable) and merge runs of a group, in case not.
    std::stable_sort(plan.group_size.begin(), plan.group_size.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    std::size_t merged = 0;
    for (std::size_t j = 0; j < plan.group_size.size(); ++j) {
      if (merged > 0 && plan.group_size[merged - 1].first == plan.group_size[j].first) {
        plan.group_size[merged - 1].second += plan.group_size[j].second;
      } else {
        plan.group_size[merged++] = plan.group_size[j];
      }
    }
    plan.group_size.resize(merged);
    plan.group_size.shrink_to_fit();
    plan.class_windows = members[k].windows.size();
    plans.push_back(std::move(plan));
  }
  members = {};  // the plans hold what the passes need

  // Pass 1: the class sums of the fit windows.
  std::size_t expected = 0;
  const auto check_order = [&](std::size_t i, const char* what) {
    if (i != expected) {
      throw Error(std::string("train_baseline: ") + what + " handed over window " + std::to_string(i) +
                  " where window " + std::to_string(expected) +
                  " was expected (the windows changed between passes)");
    }
    ++expected;
  };
  const auto check_complete = [&](const char* what) {
    if (expected != data.refs.size()) {
      throw Error(std::string("train_baseline: ") + what + " handed over " + std::to_string(expected) +
                  " of " + std::to_string(data.refs.size()) +
                  " windows (the windows changed between passes)");
    }
  };
  pass([&](std::size_t i, std::span<const float> x) {
    check_order(i, "pass 1");
    if (plan_of[i] != kNoClass && !is_held[i])
      plans[static_cast<std::size_t>(plan_of[i])].builder.add_to_mean(x);
  });
  check_complete("pass 1");
  for (Plan& p : plans) {
    p.builder.finish_mean();
    p.next_group = 0;
    if (policy.mesh_stats) {
      const ClassBaseline& c = p.builder.means();
      p.mesh.emplace(mesh_geometry(fs_hz, n, gearbox, c.segment), c.mean_magnitude);
    }
  }

  // Pass 2: each fit window's leave-one-group-out features, a group at a time in group order (a group is
  // held until all its windows have come), and the held-out windows' features against the class means.
  expected = 0;
  WindowAnalyzer analyzer(n);
  std::vector<float> mesh_mag(n / 2 + 1);
  std::vector<std::span<const float>> group_windows;
  std::vector<std::uint32_t> group_recordings;
  pass([&](std::size_t i, std::span<const float> x) {
    check_order(i, "pass 2");
    if (plan_of[i] == kNoClass) return;
    Plan& p = plans[static_cast<std::size_t>(plan_of[i])];
    if (is_held[i]) {
      std::array<Features, kMethodCount> f{};
      for (std::size_t mi = 0; mi < kMethodCount; ++mi)
        f[mi] = analyzer.analyze(x, p.builder.means(), static_cast<Method>(mi));
      p.held.push_back(f);
      return;
    }
    if (p.mesh) {
      // The mesh features need no leave-one-out (the class mean only names the mesh lines).
      analyzer.magnitude(x, mesh_mag);
      const MeshValues v = p.mesh->compute(analyzer.spectrum(), data.refs[i].speed_rad_s);
      for (std::size_t fi = 0; fi < kMeshFeatureCount; ++fi) {
        if (!std::isfinite(v.v[fi])) continue;
        p.mesh_values[fi].push_back(v.v[fi]);
        p.mesh_recording[fi].push_back(data.recording.empty() ? 0U : data.recording[i]);
      }
    }
    p.pending[group[i]].emplace_back(std::vector<float>(x.begin(), x.end()),
                                     data.recording.empty() ? 0U : data.recording[i]);
    while (p.next_group < p.group_size.size()) {
      const auto& [next_id, next_count] = p.group_size[p.next_group];
      const auto it = p.pending.find(next_id);
      if (it == p.pending.end() || it->second.size() < next_count) break;
      group_windows.clear();
      group_recordings.clear();
      for (const auto& [w, rec] : it->second) {
        group_windows.emplace_back(w);
        group_recordings.push_back(rec);
      }
      p.builder.score_group(group_windows, data.recording.empty()
                                               ? std::span<const std::uint32_t>{}
                                               : std::span<const std::uint32_t>(group_recordings));
      p.pending.erase(it);
      ++p.next_group;
    }
  });
  check_complete("pass 2");

  for (Plan& p : plans) {
    if (p.next_group != p.group_size.size() || p.held.size() != p.held_windows) {
      throw Error("train_baseline: pass 2 left windows of class " +
                  std::to_string(p.builder.means().segment.id) +
                  " unscored (the windows changed between passes)");
    }
    ClassBaseline cb = p.builder.finish();
    cb.windows_per_hour = hours > 0.0 ? static_cast<double>(p.class_windows) / hours : 0.0;
    if (p.mesh) {
      // As the band statistics: the random-effects split with the recordings as groups, the between-day
      // sd floored at day_sd_floor x within sd. Too few windows with the features (a class too slow for
      // two input-shaft revolutions per window, or without mesh lines): windows = 0, no detector.
      cb.mesh_stats.assign(kMeshFeatureCount, MeshFeatureStats{});
      for (std::size_t fi = 0; fi < kMeshFeatureCount; ++fi) {
        if (p.mesh_values[fi].size() < kMeshMinTrainingWindows) continue;
        const VarianceComponents v = variance_components(p.mesh_values[fi], p.mesh_recording[fi]);
        MeshFeatureStats& st = cb.mesh_stats[fi];
        st.mean = v.mean;
        st.within_sd = std::sqrt(v.within_var);
        st.between_est = std::sqrt(v.between_var);
        st.between_sd = std::max(st.between_est, policy.day_sd_floor * st.within_sd);
        st.windows = static_cast<std::uint32_t>(p.mesh_values[fi].size());
        if (!(st.within_sd > 0.0)) {
          st = MeshFeatureStats{};  // a constant feature cannot be standardised
          continue;
        }
        cb.mesh_recordings = std::max(cb.mesh_recordings, v.groups);
      }
    }
    if (!p.held.empty()) {
      for (std::size_t mi = 0; mi < kMethodCount; ++mi) {
        HoldoutStats& h = cb.holdout[mi];
        std::vector<double> zr;
        std::vector<double> ze;
        for (const auto& fh : p.held) {
          const Features& f = fh[mi];
          const Verdict v = judge(f, cb.thresholds[mi]);
          ++h.windows;
          h.abnormal += v.abnormal() ? 1U : 0U;
          h.rms_high += v.rms_out ? 1U : 0U;
          h.rms_low += v.rms_low ? 1U : 0U;
          h.entropy_out += v.entropy_out ? 1U : 0U;
          const StandardScores z = standardize(f, sequential_scale(cb, static_cast<Method>(mi), policy, 0.0));
          if (std::isfinite(z.rms)) zr.push_back(z.rms);
          if (std::isfinite(z.entropy)) ze.push_back(z.entropy);
        }
        const FeatureStats sr = feature_stats(zr);
        const FeatureStats se = feature_stats(ze);
        h.z_rms_mean = sr.mean;
        h.z_rms_sd = sr.stddev;
        h.z_entropy_mean = se.mean;
        h.z_entropy_sd = se.stddev;
      }
    }
    out.classes.push_back(std::move(cb));
  }
  if (out.classes.empty()) {
    std::string reasons;
    for (const std::string& w : why) reasons += "; dropped " + w;
    throw Error("train_baseline: no segment class has enough training data (needs >= " +
                std::to_string(classes.min_regions) +
                " regions and >= 3 non-overlapping window groups): " + std::to_string(data.regions.size()) +
                " regions, " + std::to_string(data.refs.size()) + " windows" +
                (unmatched > 0 ? ", " + std::to_string(unmatched) + " of them in dropped speed groups" : "") +
                (candidates.classes.empty() ? std::string("; no class learned") : summary) + reasons);
  }
  if (dropped != nullptr) dropped->insert(dropped->end(), why.begin(), why.end());
  return out;
}

}  // namespace ptda::dsp
