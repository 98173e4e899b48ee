"""demfem's studies on top of the sweep (docs/sweeps.md): each study writes a sweep file for
its settings, runs it with the sweep's pool (retries, resume, shared beds, Slurm), and reads
the members' output for its own table. `python3 -m studies --help` lists them."""
