"""Package data: the built-in regrasp problems (*.yaml); see regrasp_casadi.problem and problems/README.md."""
