// The training glue: segment classes from the regions of a healthy recording, then the baseline from
// its collected windows (build_class_baseline() per class). Offline code (and the daemon's training
// mode): allocates and throws ptda::Error. See docs/windows.md.
#include "ptda/dsp/baseline_training.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
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

std::vector<SegmentClass> learn_segment_classes_streamed(const SpillVector<RegionInfo>& regions,
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
    SpillVector<Item> items(regions.config());
    regions.for_each([&](const RegionInfo& r) {
      if ((r.direction < 0 ? -1 : 1) != dir) return;
      if (!std::isfinite(r.mean_speed_rad_s))
        throw Error("learn_segment_classes: region " + std::to_string(r.seq) +
                    " has a non-finite mean speed");
      items.push_back(
          Item{std::fabs(r.mean_speed_rad_s), static_cast<double>(r.t_end_ns - r.t_begin_ns) * 1e-9});
    });
    const SpillVector<Item> by_speed =
        sorted(items, [](const Item& a, const Item& b) { return a.speed < b.speed; });
    // Greedy: a group is anchored at its slowest region and takes every region within the anchor's
    // tolerance. Every member is then within the class tolerance of the class mean (the mean is at
    // or above the anchor, so its tolerance is at least the anchor's), so training regions always
    // match their own class.
    SpillVector<Item>::Reader rd(by_speed);
    while (!rd.done()) {
      const double anchor = rd.peek().speed;
      double sum = 0.0;
      SpillVector<double> durations(regions.config());
      while (!rd.done() && rd.peek().speed - anchor <= tol_at(anchor)) {
        const Item it = rd.next();
        sum += it.speed;
        durations.push_back(it.duration_s);
      }
      const std::size_t m = durations.size();
      if (m >= cfg.min_regions) {
        const SpillVector<double> d = sorted(durations, std::less<>());
        SegmentClass c;
        c.direction = dir;
        c.speed_rad_s = sum / static_cast<double>(m);
        c.speed_tol_rad_s = tol_at(c.speed_rad_s);
        c.duration_s = m % 2 == 1 ? d.at(m / 2) : 0.5 * (d.at(m / 2 - 1) + d.at(m / 2));
        c.regions = static_cast<std::uint32_t>(m);
        out.push_back(c);
      } else if (dropped != nullptr) {
        dropped->push_back("speed " + std::string(dir < 0 ? "-" : "+") + num(sum / static_cast<double>(m)) +
                           " rad/s: " + std::to_string(m) +
                           " region(s), fewer than classes.min_regions = " + std::to_string(cfg.min_regions));
      }
    }
  }
  for (std::size_t k = 0; k < out.size(); ++k) out[k].id = static_cast<std::uint32_t>(k);
  return out;
}

std::vector<SegmentClass> learn_segment_classes(const std::vector<RegionInfo>& regions,
                                                const ClassLearningConfig& cfg,
                                                std::vector<std::string>* dropped) {
  SpillConfig in_memory;
  in_memory.memory_bytes = std::numeric_limits<std::size_t>::max();  // never spills
  SpillVector<RegionInfo> v(in_memory);
  for (const RegionInfo& r : regions) v.push_back(r);
  return learn_segment_classes_streamed(v, cfg, dropped);
}

TrainingIndex::TrainingIndex(const SpillConfig& cfg) : spill(cfg), refs(cfg), recording(cfg), regions(cfg) {}

TrainingIndex make_training_index(const CollectedWindows& data, const SpillConfig& spill) {
  if (!data.recording.empty() && data.recording.size() != data.refs.size()) {
    throw Error("train_baseline: " + std::to_string(data.recording.size()) + " recording ids but " +
                std::to_string(data.refs.size()) + " windows");
  }
  TrainingIndex index(spill);
  for (std::size_t i = 0; i < data.refs.size(); ++i) {
    index.refs.push_back(data.refs[i]);
    index.recording.push_back(data.recording.empty() ? 0U : data.recording[i]);
  }
  for (const RegionInfo& r : data.regions) index.regions.push_back(r);
  return index;
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
  return train_baseline_streamed(make_training_index(data), n, pass, classes, policy, fs_hz, gearbox,
                                 dropped);
}

Baseline train_baseline_streamed(const TrainingIndex& data, std::size_t n, const TrainingWindowPass& pass,
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
  if (data.recording.size() != data.refs.size()) {
    throw Error("train_baseline: " + std::to_string(data.recording.size()) + " recording ids but " +
                std::to_string(data.refs.size()) + " windows");
  }
  if (data.refs.empty()) {
    throw Error("train_baseline: no constant-speed windows in the training data (" +
                std::to_string(data.regions.size()) + " regions found)");
  }
  // Every per-window list below is a spill vector: memory does not grow with the training data, and
  // whatever is sorted is sorted in bounded memory (docs/cli.md, `ptda train`, "Memory").
  const SpillConfig& sp = data.spill;
  const std::size_t count = data.refs.size();

  // Why each speed group or class is left out, for the caller and for the error below.
  std::vector<std::string> why;
  Baseline candidates;
  for (const SegmentClass& c : learn_segment_classes_streamed(data.regions, classes, &why)) {
    ClassBaseline cb;
    cb.segment = c;
    candidates.classes.push_back(std::move(cb));
  }

  // Overlap groups: windows of one region whose sample ranges overlap (directly or through a chain)
  // share a group, so leave-one-group-out never scores a window against a mean containing its own
  // samples; disjoint windows of one long region are separate groups. Ids follow (region, first sample).
  struct Place {
    std::uint64_t region_seq;
    std::int64_t first_sample;
    std::uint64_t i;
  };
  struct GroupOf {
    std::uint64_t i;
    std::uint64_t g;
  };
  SpillVector<GroupOf> group_in_cut_order(sp);
  {
    SpillVector<Place> places(sp);
    {
      std::uint64_t i = 0;
      data.refs.for_each([&](const WindowRef& r) {
        places.push_back(Place{r.region_seq, r.first_sample, i++});
      });
    }
    const SpillVector<Place> by_place = sorted(places, [](const Place& p, const Place& q) {
      return p.region_seq != q.region_seq ? p.region_seq < q.region_seq : p.first_sample < q.first_sample;
    });
    SpillVector<GroupOf> group_of(sp);
    std::uint64_t next_group = 0;
    std::int64_t reach = 0;  // end (exclusive) of the current group's samples
    bool first = true;
    std::uint64_t prev_region = 0;
    by_place.for_each([&](const Place& r) {
      const bool same_region = !first && prev_region == r.region_seq;
      if (!(same_region && r.first_sample < reach)) {
        ++next_group;
        reach = r.first_sample;
      }
      reach = std::max(reach, r.first_sample + static_cast<std::int64_t>(n));
      group_of.push_back(GroupOf{r.i, next_group - 1});
      first = false;
      prev_region = r.region_seq;
    });
    group_in_cut_order = sorted(group_of, [](const GroupOf& a, const GroupOf& b) { return a.i < b.i; });
  }

  // Each window's class, the classes' (class, group, window) members, and the gaps between windows.
  constexpr std::uint32_t kNoClass = ~std::uint32_t{0};
  struct Member {
    std::uint32_t cls;
    std::uint64_t g;
    std::uint64_t i;
  };
  SpillVector<std::uint32_t> class_of(sp);
  SpillVector<Member> member_list(sp);
  SpillVector<double> dt_s(sp);
  std::vector<std::size_t> class_windows(candidates.classes.size(), 0);
  std::size_t unmatched = 0;
  {
    SpillVector<WindowRef>::Reader refs(data.refs);
    SpillVector<GroupOf>::Reader groups(group_in_cut_order);
    std::int64_t prev_t_ns = 0;
    for (std::uint64_t i = 0; i < count; ++i) {
      const WindowRef r = refs.next();
      const std::uint64_t g = groups.next().g;
      if (i > 0) {
        const double d = static_cast<double>(r.t_start_ns - prev_t_ns) * 1e-9;
        if (d > 0.0) dt_s.push_back(d);
      }
      prev_t_ns = r.t_start_ns;
      const ClassBaseline* c = candidates.match(r.speed_rad_s);
      if (c == nullptr) {
        ++unmatched;
        class_of.push_back(kNoClass);
        continue;
      }
      const auto k = static_cast<std::uint32_t>(c - candidates.classes.data());
      class_of.push_back(k);
      member_list.push_back(Member{k, g, i});
      ++class_windows[k];
    }
  }

  // Operating time of the training data: the time from each window's start to the next one's (in cut
  // order), a pause longer than 10 median intervals (another recording, a program stop) counting as
  // one median interval; the last window adds one median interval.
  double hours = 0.0;
  if (!dt_s.empty()) {
    const double median = sorted(dt_s, std::less<>()).at(dt_s.size() / 2);
    double total = median;
    SpillVector<WindowRef>::Reader refs(data.refs);
    std::int64_t prev_t_ns = refs.next().t_start_ns;
    while (!refs.done()) {
      const std::int64_t t = refs.next().t_start_ns;
      const double d = static_cast<double>(t - prev_t_ns) * 1e-9;
      total += (d > 0.0 && d <= 10.0 * median) ? d : median;
      prev_t_ns = t;
    }
    hours = total / 3600.0;
  }
  dt_s = SpillVector<double>(sp);

  // The members by class and group (window order within a group): the distinct groups per class.
  const SpillVector<Member> members = sorted(member_list, [](const Member& a, const Member& b) {
    return a.cls != b.cls ? a.cls < b.cls : a.g < b.g;
  });
  member_list = SpillVector<Member>(sp);
  std::vector<std::size_t> distinct(candidates.classes.size(), 0);
  {
    bool first = true;
    Member prev{};
    members.for_each([&](const Member& m) {
      if (first || m.cls != prev.cls || m.g != prev.g) ++distinct[m.cls];
      first = false;
      prev = m;
    });
  }

  Baseline out;
  out.fs_hz = fs_hz;
  out.window_len = static_cast<std::uint32_t>(n);
  out.gearbox = gearbox;
  out.policy = policy;
  std::string summary;
  // What each kept class needs from the passes.
  struct Plan {
    ClassBaselineBuilder builder;
    std::uint64_t first_held = ~std::uint64_t{0};  // groups from this id on are held out
    std::size_t fit_groups = 0;
    std::size_t scored_groups = 0;
    // Fit windows of groups not yet complete (one overlap group at a time in cut order).
    std::map<std::uint64_t, std::vector<std::pair<std::vector<float>, std::uint32_t>>> pending;
    SpillVector<std::array<Features, kMethodCount>> held;  // features of the held-out windows, in cut order
    std::size_t held_windows = 0;
    std::size_t class_windows = 0;  // windows matching the class (fit and held out)
    // Mesh detector (policy.mesh_stats): the class's demodulator and its fit windows' am, pm values, by
    // recording (the values in cut order, as variance_components() of whole lists would take them).
    std::optional<MeshDemodulator> mesh;
    std::array<VarianceAccumulator, kMeshFeatureCount> mesh_values;
    std::array<std::uint32_t, kMeshFeatureCount> mesh_count{};
  };
  std::vector<Plan> plans;
  constexpr std::int32_t kNoPlan = -1;
  std::vector<std::int32_t> plan_of_class(candidates.classes.size(), kNoPlan);
  std::vector<std::size_t> n_hold_of(candidates.classes.size(), 0);
  for (std::size_t k = 0; k < candidates.classes.size(); ++k) {
    const SegmentClass& seg = candidates.classes[k].segment;
    summary += "; class " + std::to_string(seg.id) + " (" + (seg.direction < 0 ? "-" : "+") +
               num(seg.speed_rad_s) + " rad/s): " + std::to_string(seg.regions) + " regions, " +
               std::to_string(class_windows[k]) + " windows in " + std::to_string(distinct[k]) +
               " non-overlapping groups";
    if (distinct[k] < 3) {
      why.push_back(
          "speed " + std::string(seg.direction < 0 ? "-" : "+") + num(seg.speed_rad_s) +
          " rad/s: " + std::to_string(seg.regions) + " regions but its " + std::to_string(class_windows[k]) +
          " windows fall in " + std::to_string(distinct[k]) +
          " non-overlapping group(s), leave-one-group-out needs >= 3 (longer regions or more cycles)");
      continue;
    }
    // Hold-out: the latest groups (group ids follow cut order), never fewer than 3 groups left to fit.
    n_hold_of[k] = std::min(
        static_cast<std::size_t>(std::floor(policy.holdout_fraction * static_cast<double>(distinct[k]))),
        distinct[k] - 3);
    SegmentClass renumbered = seg;
    renumbered.id = static_cast<std::uint32_t>(plans.size());
    plan_of_class[k] = static_cast<std::int32_t>(plans.size());
    Plan plan{ClassBaselineBuilder(renumbered, n, policy, sp),
              ~std::uint64_t{0},
              0,
              0,
              {},
              SpillVector<std::array<Features, kMethodCount>>(sp),
              0,
              class_windows[k],
              {},
              {},
              {}};
    plans.push_back(std::move(plan));
  }
  // The first held group of each plan, the fit groups, and the last window of each fit group (in cut
  // order): a group is scored when its last window has come.
  SpillVector<std::uint64_t> lasts(sp);
  {
    std::vector<std::size_t> seen(candidates.classes.size(), 0);
    bool first = true;
    Member prev{};
    std::uint64_t last_i = 0;
    const auto close_group = [&](const Member& m, std::uint64_t last) {
      const std::int32_t pi = plan_of_class[m.cls];
      if (pi == kNoPlan) return;
      Plan& p = plans[static_cast<std::size_t>(pi)];
      if (m.g >= p.first_held) return;
      ++p.fit_groups;
      lasts.push_back(last);
    };
    members.for_each([&](const Member& m) {
      const bool new_group = first || m.cls != prev.cls || m.g != prev.g;
      if (new_group) {
        if (!first) close_group(prev, last_i);
        const std::int32_t pi = plan_of_class[m.cls];
        if (pi != kNoPlan) {
          Plan& p = plans[static_cast<std::size_t>(pi)];
          // Groups come in ascending order: the (distinct - n_hold)-th is the first held one.
          if (n_hold_of[m.cls] > 0 && seen[m.cls] == distinct[m.cls] - n_hold_of[m.cls]) p.first_held = m.g;
        }
        ++seen[m.cls];
      }
      const std::int32_t pi = plan_of_class[m.cls];
      if (pi != kNoPlan && m.g >= plans[static_cast<std::size_t>(pi)].first_held)
        ++plans[static_cast<std::size_t>(pi)].held_windows;
      last_i = std::max(last_i, m.i);
      if (new_group) last_i = m.i;
      first = false;
      prev = m;
    });
    if (!first) close_group(prev, last_i);
  }
  const SpillVector<std::uint64_t> group_ends = sorted(lasts, std::less<>());
  lasts = SpillVector<std::uint64_t>(sp);

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
    if (expected != count) {
      throw Error(std::string("train_baseline: ") + what + " handed over " + std::to_string(expected) +
                  " of " + std::to_string(count) + " windows (the windows changed between passes)");
    }
  };
  // The plan of window i and whether it is held out (readers in cut order, one step per window).
  struct Place2 {
    Plan* plan;
    bool held;
    std::uint64_t g;
  };
  const auto place_of = [&](SpillVector<std::uint32_t>::Reader& cls, SpillVector<GroupOf>::Reader& grp) {
    const std::uint32_t c = cls.next();
    const std::uint64_t g = grp.next().g;
    if (c == kNoClass || plan_of_class[c] == kNoPlan) return Place2{nullptr, false, g};
    Plan& p = plans[static_cast<std::size_t>(plan_of_class[c])];
    return Place2{&p, g >= p.first_held, g};
  };
  {
    SpillVector<std::uint32_t>::Reader cls(class_of);
    SpillVector<GroupOf>::Reader grp(group_in_cut_order);
    pass([&](std::size_t i, std::span<const float> x) {
      check_order(i, "pass 1");
      const Place2 w = place_of(cls, grp);
      if (w.plan != nullptr && !w.held) w.plan->builder.add_to_mean(x);
    });
  }
  check_complete("pass 1");
  for (Plan& p : plans) {
    p.builder.finish_mean();
    if (policy.mesh_stats) {
      const ClassBaseline& c = p.builder.means();
      p.mesh.emplace(mesh_geometry(fs_hz, n, gearbox, c.segment), c.mean_magnitude);
    }
  }

  // Pass 2: each fit window's leave-one-group-out features, a group at a time (scored when its last
  // window has come), and the held-out windows' features against the class means.
  expected = 0;
  WindowAnalyzer analyzer(n);
  std::vector<float> mesh_mag(n / 2 + 1);
  std::vector<std::span<const float>> group_windows;
  std::vector<std::uint32_t> group_recordings;
  {
    SpillVector<std::uint32_t>::Reader cls(class_of);
    SpillVector<GroupOf>::Reader grp(group_in_cut_order);
    SpillVector<WindowRef>::Reader refs(data.refs);
    SpillVector<std::uint32_t>::Reader recs(data.recording);
    SpillVector<std::uint64_t>::Reader ends(group_ends);
    pass([&](std::size_t i, std::span<const float> x) {
      check_order(i, "pass 2");
      const Place2 w = place_of(cls, grp);
      const double speed_rad_s = refs.next().speed_rad_s;
      const std::uint32_t rec = recs.next();
      if (w.plan == nullptr) return;
      Plan& p = *w.plan;
      if (w.held) {
        std::array<Features, kMethodCount> f{};
        for (std::size_t mi = 0; mi < kMethodCount; ++mi)
          f[mi] = analyzer.analyze(x, p.builder.means(), static_cast<Method>(mi));
        p.held.push_back(f);
        return;
      }
      if (p.mesh) {
        // The mesh features need no leave-one-out (the class mean only names the mesh lines).
        analyzer.magnitude(x, mesh_mag);
        const MeshValues v = p.mesh->compute(analyzer.spectrum(), speed_rad_s);
        for (std::size_t fi = 0; fi < kMeshFeatureCount; ++fi) {
          if (!std::isfinite(v.v[fi])) continue;
          p.mesh_values[fi].add(v.v[fi], rec);
          ++p.mesh_count[fi];
        }
      }
      auto& members_of_group = p.pending[w.g];
      members_of_group.emplace_back(std::vector<float>(x.begin(), x.end()), rec);
      if (ends.done() || ends.peek() != i) return;
      (void)ends.next();
      group_windows.clear();
      group_recordings.clear();
      for (const auto& [win, r] : members_of_group) {
        group_windows.emplace_back(win);
        group_recordings.push_back(r);
      }
      p.builder.score_group(group_windows, group_recordings);
      p.pending.erase(w.g);
      ++p.scored_groups;
    });
  }
  check_complete("pass 2");

  for (Plan& p : plans) {
    if (p.scored_groups != p.fit_groups || !p.pending.empty() || p.held.size() != p.held_windows) {
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
        if (p.mesh_count[fi] < kMeshMinTrainingWindows) continue;
        const VarianceComponents v = p.mesh_values[fi].result();
        MeshFeatureStats& st = cb.mesh_stats[fi];
        st.mean = v.mean;
        st.within_sd = std::sqrt(v.within_var);
        st.between_est = std::sqrt(v.between_var);
        st.between_sd = std::max(st.between_est, policy.day_sd_floor * st.within_sd);
        st.windows = p.mesh_count[fi];
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
        SpillVector<double> zr(sp);
        SpillVector<double> ze(sp);
        p.held.for_each([&](const std::array<Features, kMethodCount>& fh) {
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
        });
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
                std::to_string(classes.min_regions) + " regions and >= 3 non-overlapping window groups): " +
                std::to_string(data.regions.size()) + " regions, " + std::to_string(count) + " windows" +
                (unmatched > 0 ? ", " + std::to_string(unmatched) + " of them in dropped speed groups" : "") +
                (candidates.classes.empty() ? std::string("; no class learned") : summary) + reasons);
  }
  if (dropped != nullptr) dropped->insert(dropped->end(), why.begin(), why.end());
  return out;
}

}  // namespace ptda::dsp
