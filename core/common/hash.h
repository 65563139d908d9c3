#pragma once
// Hashing for the open-addressing tables of the front end (neighbour grid cells) and of voting
// (bins). Their keys are packed integer cell coordinates: a block of neighbouring cells is an
// arithmetic lattice of keys, which a multiplicative hash maps onto a few long runs of slots. A
// full 64-bit mix spreads them.
#include <cstdint>

namespace ism {

// splitmix64's finaliser (Steele, Lea and Flood, 2014): every input bit affects every output bit.
constexpr uint64_t mix64(uint64_t key) {
  key = (key ^ (key >> 30)) * 0xBF58476D1CE4E5B9ull;
  key = (key ^ (key >> 27)) * 0x94D049BB133111EBull;
  return key ^ (key >> 31);
}

}  // namespace ism
