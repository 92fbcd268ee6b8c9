"""`horus launch`: a robot's processes started from one YAML file (docs/launch.md). plan.py reads
the file into a Plan; the runner starts, watches and stops what the Plan lists."""
