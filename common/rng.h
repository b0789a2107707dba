#pragma once
/// Small deterministic random numbers: every pixel sample gets its own stream
/// derived from (seed, view, pixel, sample), so results do not depend on the
/// thread count or scheduling.
#include <cstdint>

namespace lp {

inline std::uint64_t SplitMix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// PCG32 (O'Neill), seeded from a hash of the stream key.
class Rng {
 public:
  explicit Rng(std::uint64_t seed, std::uint64_t a = 0, std::uint64_t b = 0, std::uint64_t c = 0) {
    const std::uint64_t s = SplitMix64(seed ^ SplitMix64(a ^ SplitMix64(b ^ SplitMix64(c))));
    state_ = 0;
    inc_ = (SplitMix64(s + 1) << 1u) | 1u;
    Next();
    state_ += s;
    Next();
  }
  std::uint32_t Next() {
    const std::uint64_t old = state_;
    state_ = old * 6364136223846793005ull + inc_;
    const auto xorshifted = static_cast<std::uint32_t>(((old >> 18u) ^ old) >> 27u);
    const auto rot = static_cast<std::uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
  }
  /// Uniform in [0, 1).
  double Uniform() { return (Next() >> 8) * (1.0 / 16777216.0); }

 private:
  std::uint64_t state_;
  std::uint64_t inc_;
};

}  // namespace lp
