"""Physical feasibility of missions: vehicle profiles, the world, constraints, planning."""
