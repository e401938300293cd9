"""CommonRoad's BMW 320i (commonroad-vehicle-models, vehicle ID 2) as start values of the Advanced FMU: its mass, yaw
inertia, axle distances, tracks, wheel radius and inertia, brake split, drive on the rear axle, load-transfer height,
and its Pacejka tire in tire slot 0 (the slot of attribute 0, the surface every wheel stands on by default).

The mapping, coefficient by coefficient (CommonRoad's vehiclemodels/utils/tire_model.py, MF without scaling factors):
  Fx0: D = p_dx1 Fz, C = p_cx1, E = p_ex1, K = p_kx1 Fz          -> PDX1, PCX1, PEX1, PKX1 (PDX2 = PEX2.. = PKX2.. = 0)
  Fy0: D = p_dy1 Fz, C = p_cy1, E = p_ey1, K = p_ky1 Fz (the form  -> PDY1, PCY1, PEY1; K proportional to Fz: PKY1 =
       CommonRoad simplifies K_y0 to)                                 p_ky1 PKY2 / 2 with PKY2 = LINEAR_KY (1 + u^2 = 1
                                                                      to 1e-10 at the loads of this car)
  combined: B_xa = r_bx1 cos(atan(r_bx2 k)), C = r_cx1, E = r_ex1   -> RBX1, RBX2, RCX1, REX1
            B_yk = r_by1 cos(atan(r_by2 (a - r_by3))), r_cy1, r_ey1 -> RBY1, RBY2, RBY3, RCY1, REY1
Left out (the Advanced model has no such terms): the shifts p_hx1 (0.0012 of slip), p_vx1 (9e-6 Fz), r_hx1, r_hy1
(0.005 and 6e-6 rad: CommonRoad normalises its combined weights so that they are 1 at zero slip) and the kappa-induced
lateral force S_vyk (r_vy*, 0 at zero longitudinal slip). p_hy1, p_vy1 act only with camber in CommonRoad (sign(0) =
0). Signs: the Advanced model uses magnitudes, so p_ky1 < 0 (ISO sign) is taken as |p_ky1|.
"""

from __future__ import annotations

LINEAR_KY = 1e6  # PKY2: Ky = 2 |PKY1 / PKY2| Fz / (1 + (Fz / (PKY2 Fz0))^2) is linear in Fz to 1e-10 at Fz ~ 5 kN


def commonroad_parameters():
    from vehiclemodels.parameters_vehicle2 import parameters_vehicle2

    return parameters_vehicle2()


def advanced_start_values(p=None, slot: int = 0) -> dict[str, float]:
    """Start values that make the Advanced FMU CommonRoad's BMW 320i on CommonRoad's tire (in `slot`); no drag, no
    rolling resistance, no compliance steer (CommonRoad's single-track drift model has none)."""
    p = p or commonroad_parameters()
    t = p.tire
    tire = {"FNOMIN": 4000.0, "PCX1": t.p_cx1, "PDX1": t.p_dx1, "PDX2": 0.0, "PEX1": t.p_ex1, "PEX2": 0.0, "PEX3": 0.0,
            "PKX1": t.p_kx1, "PKX2": 0.0, "PKX3": 0.0, "RBX1": t.r_bx1, "RBX2": t.r_bx2, "RCX1": t.r_cx1,
            "REX1": t.r_ex1, "REX2": 0.0, "PCY1": t.p_cy1, "PDY1": t.p_dy1, "PDY2": 0.0, "PEY1": t.p_ey1, "PEY2": 0.0,
            "PKY1": abs(t.p_ky1) * LINEAR_KY / 2, "PKY2": LINEAR_KY, "RBY1": t.r_by1, "RBY2": t.r_by2,
            "RBY3": t.r_by3, "RCY1": t.r_cy1, "REY1": t.r_ey1, "REY2": 0.0, "LFZO": 1.0, "LMUX": 1.0, "LMUY": 1.0,
            "LKX": 1.0, "LKY": 1.0, "LXAL": 1.0, "LYKA": 1.0}
    return {"mass": p.m, "yaw_inertia": p.I_z, "cg_to_front_axle": p.a, "cg_to_rear_axle": p.b,
            "track_front": p.T_f, "track_rear": p.T_r, "cg_height": p.h_s, "wheel_radius": p.R_w,
            "wheel_inertia": p.I_y_w, "brake_front_share": p.T_sb, "drive_front_share": p.T_se,
            "length": p.l, "width": p.w, "steer_compliance": 0.0, "drag_area": 0.0, "rolling_resistance": 0.0,
            **{f"tire{slot}_{key}": value for key, value in tire.items()}}
