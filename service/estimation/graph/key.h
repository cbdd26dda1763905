#pragma once
// Variable keys: a symbol character in the top byte and an index below, as in
// GTSAM's Symbol, so keys print as "x42" and sort by symbol then index.
#include <cstdint>
#include <string>

namespace rilo {

using Key = std::uint64_t;

constexpr Key makeKey(char symbol, std::uint64_t index) {
  return (static_cast<Key>(static_cast<unsigned char>(symbol)) << 56) | (index & 0x00FFFFFFFFFFFFFFull);
}
constexpr char keySymbol(Key k) { return static_cast<char>(k >> 56); }
constexpr std::uint64_t keyIndex(Key k) { return k & 0x00FFFFFFFFFFFFFFull; }
std::string keyString(Key k);

/// Standard variable symbols.
namespace sym {
constexpr Key X(std::uint64_t i) { return makeKey('x', i); }  ///< Pose3 T_w_b at state i
constexpr Key V(std::uint64_t i) { return makeKey('v', i); }  ///< velocity v_w_b at state i (m/s, world)
constexpr Key B(std::uint64_t i) { return makeKey('b', i); }  ///< ImuBias at state i
constexpr Key L(std::uint64_t j) { return makeKey('l', j); }  ///< anchor position p_w_anchor (m)
}  // namespace sym

}  // namespace rilo
