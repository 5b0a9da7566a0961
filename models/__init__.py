"""Package data: the shipped hand models, one folder each (URDF + hand.yaml); see
regrasp_casadi.hand_model."""
