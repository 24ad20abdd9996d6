"""Control laws shared by several papers: PID and impedance (admittance), PBVS, the hybrid blend, the
keep-out rule, the contact monitor, planar targets and the goal/gains pieces the go-to tasks share.
numpy, Pinocchio and the public framework API only; never pybullet nor a paper's package."""
