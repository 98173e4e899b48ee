#pragma once
// The two entries the DEM scene tests of rocks append to a box_scene.hpp head (rock_box()):
// a [[dem.shapes]] library of random rocks and the fill that puts them in a region
// ([[dem.insert]] or [[dem.pack]]). The defaults are the thesis's ballast scaled to a test:
// six rocks of 10 triangles drawn with seed 5, sizes normal (mean 40 mm, sd 10 mm) in
// [20, 60] mm. Tests edit the text by searching for its lines ("seed = 5", "count = 60"), so
// the keys keep this order and the values are written as given; an empty value leaves its
// key out (the reader's default applies).

#include <string>
#include <utility>

namespace demfem::test {

/// The ballast sizes of the rock tests: normal, mean 40 mm, sd 10 mm, in [20, 60] mm.
inline const std::string kBallastDistribution =
    "{ kind = \"normal\", mean = 0.04, stddev = 0.01, d_min = 0.02, d_max = 0.06 }";

/// A [[dem.shapes]] entry of kind "random_rock".
struct RandomRockShapes {
  explicit RandomRockShapes(std::string name_ = "ballast", std::string count_ = "6",
                            std::string triangles_ = "10")
      : name(std::move(name_)), count(std::move(count_)), triangles(std::move(triangles_)) {}

  std::string name;
  std::string count;
  std::string triangles;
  std::string elongation;
  std::string flatness;
  std::string seed = "5";
  std::string size;  // written quoted: "sieve"
  std::string dilation;

  std::string text() const {
    std::string t = "\n[[dem.shapes]]\nname = \"" + name + "\"\nkind = \"random_rock\"\ncount = " +
                    count + "\ntriangles = " + triangles + "\n";
    if (!elongation.empty()) t += "elongation = " + elongation + "\n";
    if (!flatness.empty()) t += "flatness = " + flatness + "\n";
    if (!seed.empty()) t += "seed = " + seed + "\n";
    if (!size.empty()) t += "size = \"" + size + "\"\n";
    if (!dilation.empty()) t += "dilation = " + dilation + "\n";
    return t;
  }
};

/// The test ballast's rocks as the rock cases shape them: elongation 0.8, `flatness`, sized
/// by sieve and dilated by 10 % of their size.
inline RandomRockShapes sieved_rocks(std::string flatness) {
  RandomRockShapes r;
  r.elongation = "0.8";
  r.flatness = std::move(flatness);
  r.size = "sieve";
  r.dilation = "0.1";
  return r;
}

/// A fill of `count` particles of `material` and `shape` in the region [0, 0, 0] .. `hi`:
/// `table` "dem.insert" (random insertion) or "dem.pack" (packed by bounding spheres).
struct RockFill {
  RockFill(std::string hi_, std::string count_, std::string seed_ = "")
      : hi(std::move(hi_)), count(std::move(count_)), seed(std::move(seed_)) {}

  std::string table = "dem.insert";
  std::string material = "rock";
  std::string shape = "ballast";
  std::string hi;  // m, e.g. "[0.3, 0.3, 0.3]"
  std::string count;
  std::string seed;
  std::string extra;  // more keys, each line ending in '\n', written before the distribution
  std::string distribution = kBallastDistribution;

  std::string text() const {
    std::string t = "\n[[" + table + "]]\nmaterial = \"" + material + "\"\nshape = \"" + shape +
                    "\"\nlo = [0.0, 0.0, 0.0]\nhi = " + hi + "\ncount = " + count + "\n";
    if (!seed.empty()) t += "seed = " + seed + "\n";
    return t + extra + "distribution = " + distribution + "\n";
  }
};

}  // namespace demfem::test
