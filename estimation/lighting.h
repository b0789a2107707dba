#pragma once
/// One scene's lighting as an estimate gives it: the environment map's radiance (the far
/// light, per cell of an EnvMap that goes with it) and the lights of every kind
/// (estimation/lights/light.h). What the rounds, the result, the viewer's status, the
/// renders and the lit shading pass around, so that a new kind of light passes through them
/// untouched.
#include <cstddef>
#include <utility>
#include <variant>
#include <vector>

#include "estimation/lights/light.h"

namespace lp {

struct Lighting {
  /// 3 per cell of the EnvMap it goes with (linear radiance, image units; 0 for left-out
  /// cells); empty: no map.
  std::vector<double> map;
  /// Every light beside the map, of any kind, in any order (an estimate gives the
  /// directional lights, then the point lights, each kind strongest first).
  std::vector<Light> lights;

  /// The lights of kind T, in order.
  template <class T>
  std::vector<T> Of() const {
    return OfKind<T>(lights);
  }
  /// How many lights of kind T.
  template <class T>
  std::size_t Count() const {
    std::size_t n = 0;
    for (const Light& l : lights) n += std::holds_alternative<T>(l);
    return n;
  }
};

/// The lights of two lists, `first`'s then `second`'s.
template <class A, class B>
std::vector<Light> Joined(const std::vector<A>& first, const std::vector<B>& second) {
  std::vector<Light> out(first.begin(), first.end());
  out.insert(out.end(), second.begin(), second.end());
  return out;
}

/// Calls `f(T{})` for each kind T of `Light`, in the variant's order (for code that has
/// one entry per kind: lights.json's keys, the exports).
template <class F>
void ForEachKind(F&& f) {
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (f(std::variant_alternative_t<I, Light>{}), ...);
  }(std::make_index_sequence<std::variant_size_v<Light>>{});
}

}  // namespace lp
