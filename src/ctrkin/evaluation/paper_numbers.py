"""The paper's reported figures, put beside ours in the report (paper Sec. III.C, IV; Tables II, III)."""

from __future__ import annotations

FK = {"position_rmse_mm": 0.69, "orientation_rmse_deg": 0.16, "ms_mean": 0.831, "ms_std": 0.200}
IK = {
    "joint_rmse_mm": 1.22,
    "joint_rmse_deg": 2.46,
    "ms_mean": 0.816,
    "ms_std": 0.200,
    "tip_error_mm": 1.0,
}  # "less than 1 mm" through the FK model (Fig. 11)
TCM_MS = {"mean": 1470.0, "std": 2930.0}  # 1.47 ± 2.930 s per point

EXPERIMENTS = {  # (position mm, orientation deg); None where the paper gives no number
    "random_points": {"tcm": (8.55, 7.88), "lstm_mlp": (0.87, 3.00)},
    "arbitrary": {"tcm": (10.94, 11.11), "lstm_mlp": (1.37, 4.87)},
    "sweeps": {"lstm_mlp_snapping_outside_snap": (0.8, 4.2), "lstm_mlp_at_snap": (12.0, 20.0)},
    "ik_square": {"lstm_mlp": (2.21, 5.88)},
    "ik_triangle": {"lstm_mlp": (2.95, 7.90)},
}
ABLATION = {"loss_decrease_pct": 72.24, "mae_decrease_pct": 75.32}  # with Δα0 (Fig. 5b)

# Table II: test MAE (normalised units) against the input buffer
TABLE2_TEST_MAE = {
    "fk": {1: 0.3243, 2: 0.1613, 3: 0.1135, 4: 0.1006, 5: 0.1115},
    "ik": {1: 0.0262, 2: 0.0159, 3: 0.0108, 4: 0.0095, 5: 0.0087},
}
# Table III: FK position (mm) and orientation (deg) error per structure at IB = 2 and 3
TABLE3 = {
    2: {"S1": (1.05, 0.58), "S2": (0.92, 0.20), "S3": (0.69, 0.16), "S4": (0.77, 0.17), "S5": (1.51, 0.40)},
    3: {"S1": (0.57, 0.13), "S2": (0.67, 0.14), "S3": (1.44, 0.53), "S4": (0.61, 0.14), "S5": (0.93, 0.19)},
}
