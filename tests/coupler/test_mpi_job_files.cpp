// MpiJobFiles (coupler/src/launch/mpi_job_files.hpp): the launcher's clean-up of an ended
// Open MPI job's shared-memory files, with a real child process carrying mpirun's job-id
// variable and real files in a temporary folder (the names Open MPI 4 and 5 give them).
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "launch/mpi_job_files.hpp"
#include "launch/supervisor.hpp"

using demfem::coupling::SolverProcess;
using demfem::coupling::launch::MpiJobFiles;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

TEST_CASE("an Open MPI shared-memory file is recognised by its job id, read from the end") {
  // 1234567 = 0x12d687; node names may hold dots; Open MPI 4.1 puts the uid before the job.
  CHECK(MpiJobFiles::is_job_file("vader_segment.vm.0.12d687.0", 1234567));
  CHECK(MpiJobFiles::is_job_file("vader_segment.node-7.cluster.org.1000.12d687.15", 1234567));
  CHECK(MpiJobFiles::is_job_file("vader_segment.vm.12d687.1", 1234567));
  CHECK(MpiJobFiles::is_job_file("sm_segment.vm.0.12d687.0", 1234567));
  CHECK_FALSE(MpiJobFiles::is_job_file("vader_segment.vm.0.12d688.0", 1234567));  // other job
  CHECK_FALSE(MpiJobFiles::is_job_file("vader_segment.vm.0.112d687.0", 1234567));  // longer id
  CHECK_FALSE(MpiJobFiles::is_job_file("vader_segment.vm.0.12d687.x", 1234567));
  CHECK_FALSE(MpiJobFiles::is_job_file("vader_segment.vm.0.12d687.", 1234567));
  CHECK_FALSE(MpiJobFiles::is_job_file("demfem-12d687.0", 1234567));
  CHECK_FALSE(MpiJobFiles::is_job_file("vader_segment..12d687.0", 1234567));
}

TEST_CASE("the files of a noted job are removed after it ended, no other file") {
  const fs::path dir = fs::temp_directory_path() /
                       ("demfem-test-mpi-files-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::vector<std::string> ours = {"vader_segment.vm.0.12d687.0",
                                         "vader_segment.vm.0.12d687.1",
                                         "sm_segment.vm.0.12d687.0"};
  const std::vector<std::string> others = {"vader_segment.vm.0.12d688.0",  // another job
                                           "demfem-0123abcd", "vader_segment.vm.0.12d687"};
  for (const auto& n : ours) std::ofstream(dir / n) << "x";
  for (const auto& n : others) std::ofstream(dir / n) << "x";

  // A rank of the job: a live process with mpirun's variable in its environment.
  SolverProcess rank("rank 0", "/bin/sleep", {"30"});
  rank.set_environment("OMPI_MCA_ess_base_jobid", "1234567");
  REQUIRE(rank.start() > 0);
  MpiJobFiles jobs;
  // /proc/<pid>/environ holds the environment from the exec on: wait until it is there.
  bool noted = false;
  for (int i = 0; i < 200 && !(noted = jobs.note_rank(rank.pid())); ++i) ::usleep(10000);
  REQUIRE(noted);
  CHECK(jobs.jobs().count(1234567) == 1);
  rank.set_after_end([&] { jobs.remove_left(dir.string()); });
  rank.stop(100ms);  // the job ends: the hook removes its files

  for (const auto& n : ours) CHECK_FALSE(fs::exists(dir / n));
  for (const auto& n : others) CHECK(fs::exists(dir / n));
  fs::remove_all(dir);
}

TEST_CASE("a process that is not an Open MPI rank notes no job") {
  MpiJobFiles jobs;
  SolverProcess plain("plain", "/bin/sleep", {"30"});
  plain.start();
  ::usleep(50000);
  CHECK_FALSE(jobs.note_rank(plain.pid()));
  const pid_t gone = plain.pid();
  plain.stop(100ms);
  CHECK_FALSE(jobs.note_rank(gone));  // ended (and reaped): nothing to read
  CHECK_FALSE(jobs.note_rank(0));
  CHECK(jobs.jobs().empty());
  CHECK(jobs.remove_left("/nonexistent-folder").empty());
}
