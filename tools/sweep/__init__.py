"""demfem sweep: parameter studies with repetitions, run locally in a process pool or on a
Slurm cluster as job arrays. Every member is an ordinary `demfem_run` in its own folder.
docs/sweeps.md describes the sweep file, the commands and the output."""
