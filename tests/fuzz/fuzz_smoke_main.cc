// Driver for fuzz_command.cc without libFuzzer (gcc builds): random inputs for N seconds,
// so the harness compiles and runs in the normal build and CI; prints inputs per second.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 10;
  std::mt19937 rng(42);
  std::uint64_t n = 0;
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < seconds) {
    std::vector<std::uint8_t> in(rng() % 300);
    for (auto& b : in) b = static_cast<std::uint8_t>(rng());
    if (!in.empty()) in[0] = static_cast<std::uint8_t>(rng() % 64);
    LLVMFuzzerTestOneInput(in.data(), in.size());
    ++n;
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%llu inputs in %.1f s: %.0f/s\n", static_cast<unsigned long long>(n), s, n / s);
}
