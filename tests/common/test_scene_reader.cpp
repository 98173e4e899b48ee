#include <catch2/catch.hpp>

#include "demfem/scene/scene_reader.hpp"

using demfem::scene::Document;
using demfem::scene::Range;
using demfem::scene::SceneError;
using Catch::Matchers::Contains;

TEST_CASE("scene reader reads typed values and rejects unknown keys", "[scene]") {
  auto doc = Document::parse(R"(
[run]
end_time = 2
name = "beam"
[dem]
dt = 1e-5
gravity = [0.0, 0.0, -9.81]
typo = 3
)",
                             "mem.toml");
  auto root = doc.root();
  auto run = root.required_table("run");
  CHECK(run.number("end_time", Range::positive()) == 2.0);
  CHECK(run.string("name") == "beam");
  CHECK(run.choice("scheme", "predictive", {"predictive", "just_in_time"}) == "predictive");
  run.finish();
  auto dem = root.required_table("dem");
  CHECK(dem.number("dt", Range::positive()) == 1e-5);
  CHECK(dem.vec3("gravity")[2] == -9.81);
  CHECK_THROWS_WITH(dem.finish(), Contains("mem.toml:8") && Contains("'dem.typo'"));
}

TEST_CASE("scene reader names file, line, key and range for bad values", "[scene]") {
  auto doc = Document::parse("[dem]\ndt = -1e-5\nn = nan\nk = \"x\"\nm = 7\n", "bad.toml");
  auto dem = doc.root().required_table("dem");
  CHECK_THROWS_WITH(dem.number("dt", Range::positive()),
                    Contains("bad.toml:2") && Contains("'dem.dt'") && Contains("> 0"));
  CHECK_THROWS_WITH(dem.number("n"), Contains("bad.toml:3") && Contains("finite"));
  CHECK_THROWS_WITH(dem.number("k"), Contains("must be a number"));
  CHECK_THROWS_WITH(dem.integer("m", 0, 5), Contains("[0, 5]"));
  CHECK_THROWS_WITH(dem.number("missing"), Contains("required"));
}

TEST_CASE("scene reader reports syntax errors and missing files", "[scene]") {
  CHECK_THROWS_WITH(Document::parse("[dem\n", "syn.toml"), Contains("syn.toml:1"));
  CHECK_THROWS_WITH(Document::load("/nonexistent/scene.toml"),
                    Contains("/nonexistent/scene.toml") && Contains("cannot open"));
}

TEST_CASE("run settings: defaults, ranges and unknown sections", "[scene]") {
  auto ok = Document::parse("[run]\nend_time = 0.5\n[dem]\nanything = 1\n", "runs/beam.toml");
  auto s = demfem::scene::read_run_settings(ok);
  CHECK(s.name == "beam");
  CHECK(s.end_time == 0.5);
  CHECK(s.output_dir == std::filesystem::path("out/beam"));
  auto bad = Document::parse("[run]\nend_time = 0.5\n[demm]\n", "s.toml");
  CHECK_THROWS_WITH(demfem::scene::read_run_settings(bad), Contains("'demm'"));
  auto neg = Document::parse("[run]\nend_time = -1\n", "s.toml");
  CHECK_THROWS_WITH(demfem::scene::read_run_settings(neg), Contains("'run.end_time'"));
}
