// Cost of one window through WindowAnalyzer::analyze() (FFTs + residual + features) for the window
// lengths the pipeline uses. The counter "cpu_s_per_signal_s" is CPU seconds spent per second of
// 25.6 kHz signal with non-overlapping windows (multiply by 1 / (1 - overlap) for overlapping ones).
#include <benchmark/benchmark.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>
#include <vector>

#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/real_fft.hpp"
#include "ptda/dsp/training.hpp"

namespace {

constexpr double kFsHz = 25600.0;

std::vector<float> gear_like_window(std::size_t n, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 2.0 * std::numbers::pi);
  std::normal_distribution<double> g(0.0, 1.0);
  const double ph1 = u(rng), ph2 = u(rng);
  std::vector<float> x(n);
  for (std::size_t t = 0; t < n; ++t) {
    const double s = static_cast<double>(t) / kFsHz;
    x[t] = static_cast<float>(1.4 * std::sin(2.0 * std::numbers::pi * 520.0 * s + ph1) +
                              0.9 * std::sin(2.0 * std::numbers::pi * 2600.0 * s + ph2) + g(rng));
  }
  return x;
}

void BM_Analyze(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto method = static_cast<ptda::dsp::Method>(state.range(1));
  std::mt19937 rng(1);
  std::vector<std::vector<float>> train;
  for (int i = 0; i < 4; ++i) train.push_back(gear_like_window(n, rng));
  const ptda::dsp::ClassBaseline cls =
      ptda::dsp::build_class_baseline(ptda::dsp::SegmentClass{}, train, {}, ptda::dsp::ThresholdPolicy{});
  const std::vector<float> x = gear_like_window(n, rng);
  ptda::dsp::WindowAnalyzer analyzer(n);
  for (auto _ : state) {
    const ptda::dsp::Features f = analyzer.analyze(x, cls, method);
    benchmark::DoNotOptimize(f);
  }
  state.SetLabel(std::string(ptda::dsp::method_name(method)));
  // Rate of seconds of signal, inverted: CPU time / signal time.
  state.counters["cpu_s_per_signal_s"] =
      benchmark::Counter(static_cast<double>(n) / kFsHz,
                         benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

BENCHMARK(BM_Analyze)
    ->ArgsProduct({{3200, 10240, 12800, 25600}, {0, 1, 2}})
    ->ArgNames({"N", "method"})
    ->Unit(benchmark::kMicrosecond);

// One forward + one inverse real FFT per iteration (the project's RealFft over KissFFT); the counter
// "us_per_transform" is half the pair, comparable with the KissFFT anchor in
// /work/shared/notes/performance-and-reliability.md (~103 us per 16384-point transform here).
void BM_RealFftPair(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  std::mt19937 rng(2);
  const std::vector<float> x = gear_like_window(n, rng);
  std::vector<float> y(n);
  std::vector<std::complex<float>> spectrum(n / 2 + 1);
  ptda::dsp::RealFft fft(n);
  for (auto _ : state) {
    fft.forward(x, spectrum);
    fft.inverse(spectrum, y);
    benchmark::DoNotOptimize(y.data());
    benchmark::ClobberMemory();
  }
  state.counters["us_per_transform"] =
      benchmark::Counter(2e-6, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

BENCHMARK(BM_RealFftPair)
    ->ArgName("N")
    ->Arg(3200)
    ->Arg(10240)
    ->Arg(12800)
    ->Arg(16384)
    ->Arg(25600)
    ->Unit(benchmark::kMicrosecond);

// The KissFFT forward transform alone (RealFft::forward): the anchor of scripts/bench.sh's ratio
// "whole per-window analysis / one forward transform" (issue 13 item 5).
void BM_RealFftForward(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  std::mt19937 rng(2);
  const std::vector<float> x = gear_like_window(n, rng);
  std::vector<std::complex<float>> spectrum(n / 2 + 1);
  ptda::dsp::RealFft fft(n);
  for (auto _ : state) {
    fft.forward(x, spectrum);
    benchmark::DoNotOptimize(spectrum.data());
    benchmark::ClobberMemory();
  }
}

BENCHMARK(BM_RealFftForward)->ArgName("N")->Arg(4096)->Arg(12800)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
