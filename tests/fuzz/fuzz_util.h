#pragma once
// What every fuzz target asserts: a parser given any bytes returns, or throws InputError
// (the one-line error a user sees); anything else escapes and libFuzzer reports it, as it
// reports a crash, a sanitizer finding, a timeout or running out of memory.
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/error.h"

namespace lp::fuzz {

inline std::string Text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

template <class F>
void ReturnsOrRefuses(F&& parse) {
  try {
    parse();
  } catch (const InputError&) {
  }
}

}  // namespace lp::fuzz
