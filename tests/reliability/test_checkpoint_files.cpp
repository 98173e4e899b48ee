// Checkpoint folders without processes: the FNV-1a 64 checksum against the published test
// vectors, commit/verify, detection of every kind of damage, and pruning to the last K.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "demfem/coupling/checkpoint.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/temp_dir.hpp"

namespace fs = std::filesystem;
using namespace demfem::coupling;

namespace {

using demfem::test::read_text;
using demfem::test::TempDir;

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

// A committed checkpoint of `step` with three small parts.
fs::path make_checkpoint(const fs::path& dir, std::int64_t step) {
  const fs::path f = dir / checkpoint_folder_name(step);
  fs::create_directories(f);
  for (const char* n : {"dem.h5", "fem.h5", "coupler.h5"}) {
    write(f / n, std::string(n) + " of step " + std::to_string(step));
  }
  commit_checkpoint(f, step, 1e-4 * static_cast<double>(step), "just_in_time",
                    {"dem.h5", "fem.h5", "coupler.h5"});
  return f;
}

std::string error_of(const fs::path& folder) {
  return demfem::test::error_of<std::exception>(
      [&] {
        (void)verify_checkpoint(folder, {"dem.h5", "fem.h5", "coupler.h5"});
      },
      "");
}

}  // namespace

TEST_CASE("FNV-1a 64 of a file matches the published test vectors") {
  // Reference values: the FNV test suite of Fowler, Noll and Vo (isthe.com/chongo/tech/comp/fnv):
  // "" -> cbf29ce484222325, "a" -> af63dc4c8601ec8c, "foobar" -> 85944171f73967e8.
  TempDir d;
  write(d.path / "empty", "");
  write(d.path / "a", "a");
  write(d.path / "foobar", "foobar");
  CHECK(fnv1a64_file(d.path / "empty") == 0xcbf29ce484222325ULL);
  CHECK(fnv1a64_file(d.path / "a") == 0xaf63dc4c8601ec8cULL);
  CHECK(fnv1a64_file(d.path / "foobar") == 0x85944171f73967e8ULL);
  CHECK_THROWS_WITH(fnv1a64_file(d.path / "nope"), Catch::Contains("nope: cannot read"));
}

TEST_CASE("a committed checkpoint verifies and reads back") {
  TempDir d;
  const fs::path f = make_checkpoint(d.path, 40);
  const CheckpointManifest m = verify_checkpoint(f, {"dem.h5", "fem.h5", "coupler.h5"});
  CHECK(m.step == 40);
  CHECK(m.time == 1e-4 * 40.0);  // written with 17 digits: exact
  CHECK(m.scheme == "just_in_time");
  REQUIRE(m.parts.size() == 3);
  CHECK(m.parts[0].size == fs::file_size(f / "dem.h5"));
  CHECK(m.parts[2].checksum == fnv1a64_file(f / "coupler.h5"));
}

TEST_CASE("every kind of damage is detected and named") {
  TempDir d;
  SECTION("truncated part") {
    const fs::path f = make_checkpoint(d.path, 10);
    fs::resize_file(f / "fem.h5", 3);
    CHECK_THAT(error_of(f), Catch::Contains("fem.h5: size 3 bytes") &&
                                Catch::Contains("(truncated or changed)"));
  }
  SECTION("same size, other bytes") {
    const fs::path f = make_checkpoint(d.path, 10);
    std::string text = "dem.h5 of step 10";
    text[0] = 'D';
    write(f / "dem.h5", text);
    CHECK_THAT(error_of(f), Catch::Contains("dem.h5: checksum") && Catch::Contains("(corrupt)"));
  }
  SECTION("missing part") {
    const fs::path f = make_checkpoint(d.path, 10);
    fs::remove(f / "coupler.h5");
    CHECK_THAT(error_of(f), Catch::Contains("coupler.h5: part missing"));
  }
  SECTION("part not listed") {
    const fs::path f = d.path / checkpoint_folder_name(10);
    fs::create_directories(f);
    write(f / "dem.h5", "x");
    write(f / "coupler.h5", "y");
    commit_checkpoint(f, 10, 0.001, "just_in_time", {"dem.h5", "coupler.h5"});
    CHECK_THAT(error_of(f), Catch::Contains("part 'fem.h5' is not listed"));
  }
  SECTION("no manifest") {
    const fs::path f = make_checkpoint(d.path, 10);
    fs::remove(f / "manifest.json");
    CHECK_THAT(error_of(f), Catch::Contains("manifest.json: missing"));
  }
  SECTION("malformed manifest: names the line") {
    const fs::path f = make_checkpoint(d.path, 10);
    write(f / "manifest.json", "{\n  \"format\": \"demfem-checkpoint-1\",\n  \"step\": ten,\n}\n");
    CHECK_THAT(error_of(f), Catch::Contains("manifest.json:3: key 'step' is malformed"));
  }
  SECTION("step does not match the folder") {
    const fs::path f = make_checkpoint(d.path, 10);
    fs::rename(f, d.path / checkpoint_folder_name(20));
    CHECK_THAT(error_of(d.path / checkpoint_folder_name(20)),
               Catch::Contains("key 'step' = 10 does not match the folder name"));
  }
}

TEST_CASE("the latest valid checkpoint is found, damaged newer ones reported") {
  TempDir d;
  make_checkpoint(d.path, 0);
  make_checkpoint(d.path, 10);
  const fs::path f20 = make_checkpoint(d.path, 20);
  fs::create_directories(d.path / checkpoint_folder_name(30));  // never committed
  fs::resize_file(f20 / "dem.h5", 1);
  std::vector<std::string> messages;
  const auto found = latest_valid_checkpoint(d.path, {"dem.h5", "fem.h5", "coupler.h5"},
                                             [&](const std::string& m) { messages.push_back(m); });
  REQUIRE(found);
  CHECK(found->filename() == "step-000010");
  REQUIRE(messages.size() == 2);
  CHECK_THAT(messages[0], Catch::Contains("step-000030") && Catch::Contains("not committed"));
  CHECK_THAT(messages[1], Catch::Contains("step-000020/dem.h5: size 1 bytes"));
  // Nothing there at all.
  CHECK_FALSE(latest_valid_checkpoint(d.path / "none", {}, {}));
}

TEST_CASE("pruning keeps the newest K committed checkpoints") {
  TempDir d;
  for (int s : {0, 10, 20, 30}) make_checkpoint(d.path, s);
  fs::create_directories(d.path / checkpoint_folder_name(5));   // stale, uncommitted
  fs::create_directories(d.path / checkpoint_folder_name(40));  // being written now
  prune_checkpoints(d.path, 2);
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(d.path)) left.push_back(e.path().filename());
  std::sort(left.begin(), left.end());
  CHECK(left == std::vector<std::string>{"step-000020", "step-000030", "step-000040"});
}
