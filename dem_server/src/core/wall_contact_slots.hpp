#pragma once
// The per-particle wall contact slots of the CPU backend (DemSystem::Impl::wall_contacts):
// kMaxWallContacts slots per particle, slot s = kMaxWallContacts * i + c for particle i's
// contact c < count[i]. The wall contact law (physics/wall_contact.hpp) fills them each force
// pass; the wall store sums the forces per wall and per flexible node from them
// (WallStore::reduce), in particle and slot order. The key and the histories belong to the
// contact and are carried from step to step (saved with the state: "wkey", "wshear", "wroll",
// "wcount"); the rest is rewritten every force pass.

#include <cstdint>
#include <vector>

namespace demfem::dem::detail {

struct WallContactSlots {
  // the contact's history
  std::vector<std::int64_t> key;        ///< feature type << 60 | feature id, -1 = empty
  std::vector<double> shear;            ///< 3 per slot: tangential spring displacement, m
  std::vector<double> rolling_history;  ///< 3 per slot: rolling-torque history, N m (if rolling)
  std::vector<std::uint8_t> count;      ///< per particle: slots in use
  // this force pass
  std::vector<double> force;           ///< 3 per slot: force on the particle, N
  std::vector<double> point;           ///< 3 per slot: contact point, m
  std::vector<double> weights;         ///< 3 per slot: barycentric weights of the point
  std::vector<std::int32_t> triangle;  ///< per slot: the triangle touched (wall store index)
};

}  // namespace demfem::dem::detail
