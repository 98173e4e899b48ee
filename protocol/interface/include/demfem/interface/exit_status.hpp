#pragma once
// The exit statuses of demfem's programs, in one place: `demfem run` (the launcher, whose
// map from what ended a run to its code is coupler/src/launch/exit_map.cpp), dem_server and
// fem_server return the run's codes below, and the protocol's serve() its own (one solver's
// view of the session). The Python SDK exports them through its bindings
// (protocol/python/bindings.cpp: demfem.EXIT_OK, ..., EXIT_BAD_INPUT). tools/sweep does not
// copy them either: it reads this file (tools/sweep/exit_status.py parses the `inline
// constexpr int kExit... = N;  ///<` lines, the short name before the first ':' is what the
// sweep prints, e.g. "exit 3 (blow-up)"), and its unit test checks that every kExit line here
// is read and that no Python file of tools/ or the SDK copies one. Keep one constant per line
// in that form. A signal ends a program with 128 + N (SIGTERM: 143) in both sets.

namespace demfem {

// The run's codes: `demfem run`, dem_server, fem_server; the sweep's members and the sweep.
// 0: the run (or the check) finished.
/// A failure while running: an engine or I/O error, a solver that died or did not attach,
/// a post step that failed. The sweep retries a member from its last checkpoint.
inline constexpr int kExitFailed = 1;  ///< failed: a failure while running (engine, I/O)
/// A bad command line, scene, model or checkpoint to resume from: nothing (more) was run and
/// another attempt would only repeat the message (after --resume: no valid checkpoint left).
inline constexpr int kExitBadInput = 2;  ///< bad input: command line, scene, model, checkpoint
/// The coupled solution blew up (a step that does not converge with on_nonconvergence =
/// "stop", a solver reporting a blow-up): deterministic, the same steps blow up again.
inline constexpr int kExitBlowUp = 3;  ///< blow-up: the coupled solution diverged
/// The same solver kept dying: checkpoint.max_retries restarts from one checkpoint failed.
inline constexpr int kExitRecoveryExhausted = 4;  ///< a solver kept dying: recovery exhausted
/// demfem_run could not be started at all (as a shell reports a missing program); only the
/// sweep reports it, for a member whose program it could not start.
inline constexpr int kExitNotStarted = 127;  ///< demfem_run could not be started: no program

}  // namespace demfem

namespace demfem::protocol {

// serve()'s codes (protocol/ipc/src/serve.cpp): what a solver process returns when it serves
// the protocol. dem_server and fem_server return them as they are; the launcher reads them
// as one solver's end (a dead coupler, a refused Hello).
inline constexpr int kExitOk = 0;  ///< ok: Shutdown arrived, the session ended cleanly
inline constexpr int kExitBackendError = 1;  ///< backend error: the backend threw (sent as Error)
inline constexpr int kExitCouplerDied = 2;   ///< coupler died: its pid gone or heartbeat stale
inline constexpr int kExitVersionMismatch = 3;  ///< version mismatch: Hello refused
/// Cannot attach to the segment, a bad message, the role already taken, the wrong role.
inline constexpr int kExitProtocolError = 4;  ///< protocol error: attach, message or role

}  // namespace demfem::protocol
