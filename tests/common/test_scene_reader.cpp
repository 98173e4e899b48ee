#include <catch2/catch.hpp>

#include "demfem/scene/scene_reader.hpp"
#include "demfem_test/error_of.hpp"

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
  CHECK(s.peer_timeout == 10.0);
  auto quick = Document::parse("[run]\nend_time = 1\npeer_timeout = 0.5\n", "s.toml");
  CHECK(demfem::scene::read_run_settings(quick).peer_timeout == 0.5);
  // Below four heartbeat periods (50 ms each) a healthy process would be declared hung.
  auto tiny = Document::parse("[run]\nend_time = 1\npeer_timeout = 0.1\n", "s.toml");
  CHECK_THROWS_WITH(demfem::scene::read_run_settings(tiny),
                    Contains("s.toml:3") && Contains("'run.peer_timeout'") && Contains("0.2"));
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

TEST_CASE("run.name is one folder name: path separators, '..' and odd characters refused",
          "[scene]") {
  // run.name = "../../x" used to write outside out/ (issue 19, defect 13).
  auto name_error = [](const std::string& name) {
    return demfem::test::error_of<demfem::scene::SceneError>(
        [&] {
          demfem::scene::read_run_settings(
              Document::parse("[run]\nend_time = 1\nname = \"" + name + "\"\n", "n.toml"));
        },
        "");
  };
  CHECK_THAT(name_error("../../x"), Contains("n.toml:3:8: key 'run.name'") &&
                                        Contains("starts with '.'") && Contains("run.output_dir"));
  CHECK_THAT(name_error("a/b"), Contains("'/' (a path separator)"));
  CHECK_THAT(name_error("a\\\\b"), Contains("(a path separator)"));
  CHECK_THAT(name_error(".."), Contains("key 'run.name'"));
  CHECK_THAT(name_error("-rf"), Contains("starts with '-'"));
  CHECK_THAT(name_error("a b"), Contains("contains ' '"));
  CHECK_THAT(name_error("x\\ty"), Contains("a control code"));
  CHECK_THAT(name_error(std::string(129, 'a')), Contains("longer than 128"));
  CHECK_THAT(name_error(""), Contains("must not be empty"));
  for (const char* ok : {"beam", "beam_1.2-a+b=c,d@e", "a..b", "\xe6\xa2\x81"}) {
    INFO(ok);
    CHECK(name_error(ok).empty());
  }
}

TEST_CASE("a missing required key names the misspelt key beside it", "[scene]") {
  auto doc = Document::parse(R"([dem]
dt = 1e-5
[[dem.lattice]]
material = "steel"
lo = [0, 0, 0]
hi = [1, 1, 1]
diamter = 0.024
velocity = [0, 0, 0]
)",
                             "typo.toml");
  auto dem = doc.root().required_table("dem");
  auto lattice = dem.tables("lattice").at(0);
  CHECK(lattice.string("material") == "steel");
  // 'velocity' is present and not read yet, but it is no misspelling of 'diameter'; the
  // unknown 'diamter' is, and the message names it with its line.
  CHECK_THROWS_WITH(lattice.number("diameter", Range::positive()),
                    Contains("typo.toml:") && Contains("key 'dem.lattice[0].diameter'") &&
                        Contains("is required but missing") && Contains("'diamter' (line 7)") &&
                        Contains("not a known key here") && Contains("did you mean 'diameter'?"));
  // Without a look-alike, the plain message.
  CHECK_THROWS_WITH(lattice.number("spacing"), Contains("is required but missing") &&
                                                   !Contains("did you mean"));
  // A key asked for before is known, not a misspelling ('lo' then a missing 'l0' style).
  auto doc2 = Document::parse("[t]\nd_max = 2\n", "short.toml");
  auto t = doc2.root().required_table("t");
  CHECK_THROWS_WITH(t.number("d_min"), !Contains("did you mean"));  // 2 substitutions apart
  auto doc3 = Document::parse("[p]\nb = \"x\"\ndtt = 1\n", "p.toml");
  auto p = doc3.root().required_table("p");
  CHECK_THROWS_WITH(p.string("a"), !Contains("did you mean"));  // 'b' is no misspelling of 'a'
  CHECK_THROWS_WITH(p.number("dt"), Contains("'dtt' (line 3)") && Contains("did you mean 'dt'?"));
  // A misspelt required table ([rnu] for [run]).
  auto doc4 = Document::parse("[rnu]\nend_time = 1\n", "r.toml");
  CHECK_THROWS_WITH(demfem::scene::read_run_settings(doc4),
                    Contains("key 'run'") && Contains("'rnu' (line 1)") &&
                        Contains("did you mean 'run'?"));
}

TEST_CASE("an unknown key suggests the closest key the section knows", "[scene]") {
  auto doc = Document::parse("[c]\nscheme = \"x\"\nforce_averagin = true\nzzz = 1\n", "c.toml");
  auto c = doc.root().required_table("c");
  CHECK(c.string("scheme") == "x");
  CHECK_FALSE(c.boolean("force_averaging", false));  // absent under its right name
  CHECK_THROWS_WITH(c.finish(), Contains("c.toml:3") && Contains("'c.force_averagin'") &&
                                    Contains("did you mean 'force_averaging'?"));
  CHECK(demfem::scene::key_distance("diamter", "diameter") == 1);
  CHECK(demfem::scene::key_distance("DT", "dt") == 0);
  CHECK(demfem::scene::key_distance("restitution", "restituiton") == 1);  // transposition
  CHECK(demfem::scene::is_misspelling("youngs_modulos", "youngs_modulus"));
  CHECK_FALSE(demfem::scene::is_misspelling("hi", "lo"));
}
