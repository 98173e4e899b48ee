// --set KEY=VALUE on a parsed scene (scene::Document): what it may change, what it refuses,
// and that messages about an overridden key name the override instead of a line.
#include <catch2/catch.hpp>

#include <string>
#include <vector>

#include "demfem/scene/scene_reader.hpp"
#include "demfem_test/error_of.hpp"

using Catch::Matchers::Contains;
using demfem::scene::Document;
using demfem::scene::Override;
using demfem::scene::Range;
using demfem::scene::SceneError;

namespace {

const char* kScene = R"([run]
end_time = 0.5
[dem]
dt = 1e-5
gravity = [0.0, 0.0, -9.81]
backend = "cpu"
[[dem.pairs]]
a = "s"
friction = 0.3
[[dem.pairs]]
a = "t"
friction = 0.4
[fem.mesh.box]
cells = [2, 2, 2]
)";

Document with(std::vector<std::string> sets) {
  std::vector<Override> o;
  for (const auto& s : sets) o.push_back(Override::parse(s));
  return Document::parse(kScene, "cases/s.toml", o);
}

}  // namespace

TEST_CASE("scene override (--set) replaces values of any type, in tables and array entries",
          "[scene]") {
  auto doc = with({"dem.pairs[1].friction=0.75", "run.seed=7", "dem.backend=\"cuda\"",
                   "dem.gravity=[1, 2, 3]", "fem.mesh.box.cells[2]=5", "dem.dt=2e-6 # comment"});
  auto root = doc.root();
  auto run = root.required_table("run");
  CHECK(run.integer("seed", 0, 100) == 7);
  CHECK(run.number("end_time") == 0.5);  // untouched
  auto dem = root.required_table("dem");
  CHECK(dem.number("dt") == 2e-6);
  CHECK(dem.string("backend") == "cuda");
  CHECK(dem.vec3("gravity") == std::array<double, 3>{1.0, 2.0, 3.0});
  auto pairs = dem.tables("pairs");
  REQUIRE(pairs.size() == 2);
  CHECK(pairs[0].number("friction") == 0.3);
  CHECK(pairs[1].number("friction") == 0.75);
  auto box = root.required_table("fem").required_table("mesh").required_table("box");
  CHECK(box.numbers("cells", 3) == std::vector<double>{2, 2, 5});
}

TEST_CASE(
    "scene override (--set): the last override of a key wins, a new key of an existing table is "
    "added",
    "[scene]") {
  auto doc = with({"run.seed=3", "run.seed=4", "dem.threads=2"});
  CHECK(doc.root().required_table("run").integer("seed", 0, 100) == 4);
  auto dem = doc.root().required_table("dem");
  CHECK(dem.integer("threads", 0, 4096) == 2);
  CHECK(doc.overrides().size() == 3);
  // An added key that no reader knows is refused like a misspelt key in the file.
  auto typo = with({"dem.frction=1"});
  auto t = typo.root().required_table("dem");
  (void)t.number("dt");
  (void)t.vec3("gravity");
  (void)t.string("backend");
  (void)t.tables("pairs");
  CHECK_THROWS_WITH(t.finish(), Contains("cases/s.toml: key 'dem.frction' (from --set "
                                         "dem.frction=1): is not a known key here"));
}

TEST_CASE("scene override (--set): a reader's message about an overridden key names the override",
          "[scene]") {
  auto doc = with({"dem.pairs[0].friction=-1", "dem.gravity[1]=\"up\""});
  auto dem = doc.root().required_table("dem");
  CHECK_THROWS_WITH(dem.tables("pairs")[0].number("friction", Range::non_negative()),
                    Contains("cases/s.toml: key 'dem.pairs[0].friction' (from --set "
                             "dem.pairs[0].friction=-1): is -1, outside the accepted range >= 0"));
  CHECK_THROWS_WITH(dem.vec3("gravity"),
                    Contains("key 'dem.gravity' (from --set dem.gravity[1]=\"up\")") &&
                        Contains("must be a number"));
  // A key next to an overridden one keeps its file line.
  auto other = with({"dem.pairs[0].friction=0.1"});
  CHECK_THROWS_WITH(other.root().required_table("dem").tables("pairs")[1].number(
                        "friction", Range::closed(0.0, 0.2)),
                    Contains("cases/s.toml:12:") && !Contains("--set"));
  // Keys read inside a table given as an inline table by --set name the override too.
  auto inl = with({"fem.mesh.box={ cells = [1, 1, 1] }"});
  auto box = inl.root().required_table("fem").required_table("mesh").required_table("box");
  CHECK_THROWS_WITH(box.vec3("lo"), Contains("key 'fem.mesh.box.lo' (from --set fem.mesh.box="));
}

TEST_CASE("scene override (--set) refuses malformed overrides and keys the scene does not have",
          "[scene]") {
  CHECK_THROWS_AS(Override::parse("run.seed"), SceneError);
  CHECK_THROWS_WITH(Override::parse("=3"), Contains("--set =3: expected KEY=VALUE"));
  CHECK_THROWS_WITH(Override::parse("run.seed="), Contains("expected KEY=VALUE"));
  auto refused = [](const std::string& set) {
    return demfem::test::error_of<SceneError>([&] { (void)with({set}); }, "accepted");
  };
  // VALUE must be exactly one TOML value; bare words are not strings.
  CHECK_THAT(refused("dem.backend=cuda"),
             Contains("cases/s.toml: --set dem.backend=cuda: VALUE is not a TOML value") &&
                 Contains("strings need quotes"));
  CHECK_THAT(refused("run.seed=1\nx = 2"), Contains("VALUE must be one TOML value"));
  CHECK_THAT(refused("run.seed=[1,"), Contains("VALUE is not a TOML value"));
  // KEY syntax.
  CHECK_THAT(refused("dem..dt=1"), Contains("KEY has an empty or non-bare segment"));
  CHECK_THAT(refused("dem.pairs[x].friction=1"), Contains("malformed array index"));
  CHECK_THAT(refused("dem.pairs[0]friction=1"), Contains("unexpected 'f'"));
  CHECK_THAT(refused("\"dem\".dt=1"), Contains("non-bare segment at character 1"));
  // Tables and array entries are never created.
  CHECK_THAT(refused("checkpoint.every_steps=1"),
             Contains("--set checkpoint.every_steps=1: the scene has no table 'checkpoint'"));
  CHECK_THAT(refused("dem.walls[0].material=\"s\""), Contains("no array 'dem.walls'"));
  CHECK_THAT(refused("dem.pairs[2].friction=0.1"),
             Contains("the scene has no 'dem.pairs[2]' ('dem.pairs' has 2 entries)"));
  CHECK_THAT(refused("dem.gravity[3]=0"), Contains("no 'dem.gravity[3]'"));
  CHECK_THAT(refused("dem.dt.x=1"), Contains("'dem.dt' is not a table"));
  CHECK_THAT(refused("dem.backend[0]=1"), Contains("'dem.backend' is not an array"));
  // Non-ASCII that toml++ 3.3 mishandles is refused in VALUE as in files.
  CHECK_THAT(refused("run.name=\"caf\xc3\xa9\""), Contains("U+00E9"));
}

TEST_CASE(
    "scene override (--set) under [dem.load] pass: applied where the scene has its table, "
    "else only passed on",
    "[scene]") {
  const std::string scene = std::string(kScene) + R"(
[dem.load]
scene = "bed.toml"
pass = ["run.seed", "dem.shapes", "dem.pairs[1]"]
)";
  auto parse = [&](std::vector<std::string> sets) {
    std::vector<Override> o;
    for (const auto& s : sets) o.push_back(Override::parse(s));
    return Document::parse(scene, "cases/load.toml", o);
  };
  // dem.shapes is the bed's (this scene has none): kept in the list for the prepare scene
  const auto doc = parse({"dem.shapes[0].triangles=30", "run.seed=4", "dem.pairs[1].friction=0.9"});
  REQUIRE(doc.root().overrides().size() == 3);
  CHECK(doc.root().overrides()[0].key == "dem.shapes[0].triangles");
  CHECK_FALSE(doc.root().required_table("dem").has("shapes"));
  // the ones whose tables exist here are applied here too
  CHECK(doc.root().required_table("run").integer("seed", 0, 100) == 4);
  CHECK(doc.root().required_table("dem").tables("pairs")[1].number("friction") == 0.9);
  // an entry this scene lacks, under a pass prefix: passed on only
  CHECK_NOTHROW(parse({"dem.pairs[1].restitution=0.5"}));  // a new key of an existing table
  CHECK_NOTHROW(parse({"dem.shapes.count=3"}));
  // not under a pass prefix: refused as before, naming the override
  CHECK_THROWS_WITH(parse({"dem.insert[0].count=3"}),
                    Contains("--set dem.insert[0].count=3") && Contains("has no array"));
  CHECK_THROWS_WITH(parse({"dem.pairs[0].shapes[2]=1"}), Contains("has no array"));
  // Override::under: a prefix covers the key and the keys below it, not a longer name
  CHECK(Override::parse("dem.pairs[0].friction=1").under("dem.pairs"));
  CHECK(Override::parse("dem.pairs=1").under("dem.pairs"));
  CHECK_FALSE(Override::parse("dem.pairsx=1").under("dem.pairs"));
  CHECK_FALSE(Override::parse("dem.pair=1").under("dem.pairs"));
}
