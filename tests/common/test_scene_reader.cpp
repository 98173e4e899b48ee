#include <catch2/catch.hpp>

#include "demfem/scene/scene_reader.hpp"

using Catch::Matchers::Contains;
using demfem::scene::Document;
using demfem::scene::Range;
using demfem::scene::SceneError;

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
  // Issue 19: a directory said "key 'run' is required"; /dev/zero grew to 4 GB.
  CHECK_THROWS_WITH(Document::load(DEMFEM_SOURCE_DIR "/cases"),
                    Contains("/cases: is a directory, not a regular file; expected a scene file"));
  CHECK_THROWS_AS(Document::load("/dev/zero"), demfem::scene::SceneError);
  CHECK_THROWS_WITH(Document::load("/dev/zero"),
                    Contains("/dev/zero: is a character device, not a regular file"));
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

TEST_CASE("scene reader guards toml++ against code points it mishandles", "[scene]") {
  // Comments may hold any text (e.g. Greek letters for symbols).
  auto ok =
      Document::parse("# time step \xce\x94t (s)\n[run]\nend_time = 1 # \xce\x94t\n", "u.toml");
  CHECK(ok.root().required_table("run").number("end_time") == 1.0);
  // U+FEFC in a key position: invalid TOML, refused with line and column.
  CHECK_THROWS_WITH(Document::parse("ru\xef\xbb\xbc)#[ru", "k.toml"), Contains("k.toml:1:3"));
  // U+00E9 inside a string would reach undefined behaviour in toml++ 3.3: refused.
  CHECK_THROWS_WITH(Document::parse("[run]\nname = \"caf\xc3\xa9\"\n", "s.toml"),
                    Contains("s.toml:2:") && Contains("U+00E9"));
  // Characters outside those ranges pass through strings unchanged.
  auto cjk = Document::parse("[run]\nname = \"\xe6\xa2\x81\"\n", "c.toml");
  CHECK(cjk.root().required_table("run").string("name") == "\xe6\xa2\x81");
}
