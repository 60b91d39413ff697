"""The rotor model's and the controllers' arithmetic, compiled with numba (in robot, below control, which uses
it): a control tick is one call instead of some hundred Python operations on small numpy arrays, whose per-call
overhead would be most of the flight's cost.

All compiled functions live in this one module: numba's on-disk cache notices edits to
the file that defines a function, not to the files of the functions it calls.

The flight must come out as the numpy controller flew it, to the bit, so every step is
the one numpy and Python took: elementwise operations in the same order (numba without
fast-math neither reassociates nor fuses multiply-adds on its own), the matrix products
summed in the order, and with the fused multiply-adds, of the OpenBLAS kernels numpy
called (dgemv_t, ddot and dgemm of OpenBLAS's Haswell kernels, which it also runs on
Zen), and hypot as CPython computes it. sqrt is the instruction; sin, cos, asin and exp
are the C library's, as in Python.

A PID is an array of parameters (the offsets P_GAIN .. BOUNDS_OUTPUT, PID_PARAMS values) and
an array of state (INTEGRAL .. HAS_PREVIOUS, PID_STATE values), three components each.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

# PID parameters: p, i, d and the output limit (3 each), the integral's bound, dt, and flags (1.0: yes): has a d
# term, bounds its integral, bounds its output.
P_GAIN, I_GAIN, D_GAIN, LIMIT = 0, 3, 6, 9
INTEGRAL_LIMIT, DT, HAS_D, BOUNDS_INTEGRAL, BOUNDS_OUTPUT = 12, 13, 14, 15, 16
PID_PARAMS = 17
# PID state: the integral, the previous error, whether there is one.
INTEGRAL, PREVIOUS, HAS_PREVIOUS = 0, 3, 6
PID_STATE = 7
# UavController constants (given at run time, not read from other modules: the cache would not see them change).
MASS, TILT_SLOPE, G, ATTITUDE_GAIN = 0, 1, 2, 3  # attitude gains: roll, pitch, yaw
UAV_CONSTANTS = 6


_compiled = njit(cache=True, error_model="numpy")  # numpy's error model: x/0 is inf or nan, as it was


@intrinsic
def _fma(typingctx, a, b, c):
    """a·b + c with one rounding (llvm.fma: the FMA instruction, or libm's fma where there is none)."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):
        return builder.fma(*args)

    return signature, codegen


# ------------------------------------------------------------------------------------------------ arithmetic


@_compiled
def _norm2(x, y, top):
    """CPython's vector_norm for two finite values ≥ 0 with top = max(x, y) > 0 and normal."""
    _, exponent = math.frexp(top)
    scale = math.ldexp(1.0, -exponent)
    total, frac1, frac2 = 1.0, 0.0, 0.0
    for value in (x, y):
        value *= scale  # lossless
        square = value * value
        frac1 += _fma(value, value, -square)  # the square's rounding error, exactly
        new = total + square
        frac2 += (total - new) + square
        total = new
    h = math.sqrt(total - 1.0 + (frac1 + frac2))
    square = -h * h
    frac1 += _fma(-h, h, -square)
    new = total + square
    frac2 += (total - new) + square
    total = new
    h += (total - 1.0 + (frac1 + frac2)) / (2.0 * h)
    return h / scale


@_compiled
def hypot(x, y):
    """math.hypot(x, y) as CPython computes it (scaling, exact squares, compensated sum, corrected root): libm's
    hypot, which numba would call, differs from it in the last bit now and then."""
    x, y = abs(x), abs(y)
    top = 0.0
    if x > top:
        top = x
    if y > top:
        top = y
    if math.isinf(top):
        return top
    if math.isnan(x) or math.isnan(y):
        return math.nan
    if top == 0.0:
        return top
    smallest = 2.2250738585072014e-308  # DBL_MIN: below it CPython first scales the subnormals up
    if top < smallest:
        return smallest * _norm2(x / smallest, y / smallest, top / smallest)
    return _norm2(x, y, top)


@_compiled
def inner3(a0, a1, a2, b0, b1, b2):
    """numpy's dot of two 3-vectors (OpenBLAS ddot): summed left to right from 0.0."""
    return 0.0 + a0 * b0 + a1 * b1 + a2 * b2


@_compiled
def gemv_row3(a0, a1, a2, x0, x1, x2):
    """One row of numpy's (3, 3) · 3-vector (OpenBLAS dgemv_t, three columns): a1·x1, then fused a0·x0, a2·x2."""
    return 0.0 + _fma(a2, x2, _fma(a0, x0, a1 * x1))


@_compiled
def gemm_entry3(a0, a1, a2, b0, b1, b2):
    """One entry of numpy's (3, 3) · (3, 3) (OpenBLAS dgemm): fused multiply-adds from 0.0, stored onto 0.0."""
    total = _fma(a0, b0, 0.0)
    total = _fma(a1, b1, total)
    total = _fma(a2, b2, total)
    return _fma(total, 1.0, 0.0)


@_compiled
def _row9_4x2(matrix, row, x):
    """Row 0 or 1 of gemv_rows9: the 4x2 kernel sums even and odd columns in two SSE lanes."""
    even = odd = 0.0
    for k in range(0, 8, 2):
        even = even + matrix[row, k] * x[k]
        odd = odd + matrix[row, k + 1] * x[k + 1]
    return _fma(matrix[row, 8], x[8], _fma(even + odd, 1.0, 0.0))


@_compiled
def gemv_rows9(matrix, x):
    """numpy's (3, 9) · 9-vector (OpenBLAS dgemv_t): rows 0 and 1 by the 4x2 kernel, row 2 by the 4x1 kernel (two
    pairs of lanes), over the first eight columns; the result stored onto 0.0, then the ninth column fused on."""
    m = matrix
    lane0 = ((0.0 + m[2, 0] * x[0]) + m[2, 4] * x[4]) + ((0.0 + m[2, 2] * x[2]) + m[2, 6] * x[6])
    lane1 = ((0.0 + m[2, 1] * x[1]) + m[2, 5] * x[5]) + ((0.0 + m[2, 3] * x[3]) + m[2, 7] * x[7])
    return _row9_4x2(m, 0, x), _row9_4x2(m, 1, x), _fma(m[2, 8], x[8], _fma(lane0 + lane1, 1.0, 0.0))


@_compiled
def gemv_row4(matrix, row, x0, x1, x2, x3):
    """One row of numpy's (4, 4) · 4-vector (OpenBLAS dgemv_t Haswell 4x4 kernel): AVX lanes, halves added."""
    lane0 = _fma(matrix[row, 0], x0, 0.0)
    lane1 = _fma(matrix[row, 1], x1, 0.0)
    lane2 = _fma(matrix[row, 2], x2, 0.0)
    lane3 = _fma(matrix[row, 3], x3, 0.0)
    return 0.0 + ((lane0 + lane2) + (lane1 + lane3)) * 1.0


# ------------------------------------------------------------------------------------------------ controllers


@_compiled
def pid_update(params, state, e0, e1, e2, use_rate, r0, r1, r2):
    """PID output for the error (e0, e1, e2); (r0, r1, r2) is its rate where use_rate, else a finite difference."""
    dt = params[DT]
    s0 = state[INTEGRAL] + params[I_GAIN] * e0 * dt
    s1 = state[INTEGRAL + 1] + params[I_GAIN + 1] * e1 * dt
    s2 = state[INTEGRAL + 2] + params[I_GAIN + 2] * e2 * dt
    if params[BOUNDS_INTEGRAL] != 0.0:  # clamping to ±inf would change nothing, not even the sign of a zero
        b = params[INTEGRAL_LIMIT]
        s0 = -b if s0 < -b else b if s0 > b else s0
        s1 = -b if s1 < -b else b if s1 > b else s1
        s2 = -b if s2 < -b else b if s2 > b else s2
    state[INTEGRAL], state[INTEGRAL + 1], state[INTEGRAL + 2] = s0, s1, s2
    u0, u1, u2 = params[P_GAIN] * e0 + s0, params[P_GAIN + 1] * e1 + s1, params[P_GAIN + 2] * e2 + s2
    if params[HAS_D] != 0.0:
        if not use_rate:
            if state[HAS_PREVIOUS] == 0.0:
                r0, r1, r2 = 0.0 * e0, 0.0 * e1, 0.0 * e2
            else:
                r0, r1, r2 = (e0 - state[PREVIOUS]) / dt, (e1 - state[PREVIOUS + 1]) / dt, (e2 - state[PREVIOUS + 2]) / dt
            state[PREVIOUS], state[PREVIOUS + 1], state[PREVIOUS + 2], state[HAS_PREVIOUS] = e0, e1, e2, 1.0
        u0 += params[D_GAIN] * r0
        u1 += params[D_GAIN + 1] * r1
        u2 += params[D_GAIN + 2] * r2
    if params[BOUNDS_OUTPUT] != 0.0:
        c0, c1, c2 = params[LIMIT], params[LIMIT + 1], params[LIMIT + 2]
        u0 = -c0 if u0 < -c0 else c0 if u0 > c0 else u0
        u1 = -c1 if u1 < -c1 else c1 if u1 > c1 else u1
        u2 = -c2 if u2 < -c2 else c2 if u2 > c2 else u2
    return u0, u1, u2


@_compiled
def arm_torques(pid_params, pid_state, max_torque, q, qd, q_ref, qd_ref, qdd_ref, mass, bias):
    """Joint torques through the arm's (3, 3) mass matrix plus bias, clamped; and the joint accelerations asked for."""
    f0, f1, f2 = pid_update(pid_params, pid_state, q_ref[0] - q[0], q_ref[1] - q[1], q_ref[2] - q[2],
                            True, qd_ref[0] - qd[0], qd_ref[1] - qd[1], qd_ref[2] - qd[2])
    a0, a1, a2 = qdd_ref[0] + f0, qdd_ref[1] + f1, qdd_ref[2] + f2
    t0 = gemv_row3(mass[0, 0], mass[0, 1], mass[0, 2], a0, a1, a2) + bias[0]
    t1 = gemv_row3(mass[1, 0], mass[1, 1], mass[1, 2], a0, a1, a2) + bias[1]
    t2 = gemv_row3(mass[2, 0], mass[2, 1], mass[2, 2], a0, a1, a2) + bias[2]
    c = max_torque
    t0 = -c if t0 < -c else c if t0 > c else t0
    t1 = -c if t1 < -c else c if t1 > c else t1
    t2 = -c if t2 < -c else c if t2 > c else t2
    return (t0, t1, t2), (a0, a1, a2)


@_compiled
def mix(k_inv, top, thrust, m0, m1, m2):
    """Rotor speeds for the wrench (thrust, moments), each clamped to [0, max speed], and whether any was clamped."""
    w0 = gemv_row4(k_inv, 0, thrust, m0, m1, m2)
    w1 = gemv_row4(k_inv, 1, thrust, m0, m1, m2)
    w2 = gemv_row4(k_inv, 2, thrust, m0, m1, m2)
    w3 = gemv_row4(k_inv, 3, thrust, m0, m1, m2)
    saturated = min(w0, w1, w2, w3) < 0.0 or max(w0, w1, w2, w3) > top
    s0 = 0.0 if w0 < 0.0 else math.sqrt(top if w0 > top else w0)
    s1 = 0.0 if w1 < 0.0 else math.sqrt(top if w1 > top else w1)
    s2 = 0.0 if w2 < 0.0 else math.sqrt(top if w2 > top else w2)
    s3 = 0.0 if w3 < 0.0 else math.sqrt(top if w3 > top else w3)
    return (s0, s1, s2, s3), saturated


@_compiled
def lag(current, alpha, c0, c1, c2, c3):
    """The rotor speeds after one tick of the first-order motor lag toward (c0..c3), written into `current`;
    alpha < 0: no lag."""
    if alpha < 0.0:
        current[0], current[1], current[2], current[3] = c0, c1, c2, c3
    else:
        current[0] = current[0] + alpha * (c0 - current[0])
        current[1] = current[1] + alpha * (c1 - current[1])
        current[2] = current[2] + alpha * (c2 - current[2])
        current[3] = current[3] + alpha * (c3 - current[3])


@_compiled
def about_z(product, i, rate):
    """Row i of productᵀ · (0, 0, rate), rounded as numpy's gemv rounds it: the zero terms first, then one fused
    multiply-add (exact here, so written plainly), stored onto 0.0; that keeps even the signs of zeros."""
    return 0.0 + ((product[1, i] * 0.0 + product[0, i] * 0.0) + product[2, i] * rate)


@_compiled
def uav_wrench(position_params, position_state, velocity_params, velocity_state, rate_params, rate_state, constants,
               position, velocity, rotation, body_rates, ref_position, ref_velocity, ref_acceleration, yaw, yaw_rate,
               yaw_acceleration, rotational_mass, bias, arm_acceleration):
    """The cascade from position to the wanted wrench (thrust along body z, moments about body x, y, z); the
    tuples are 3-vectors of floats, the arrays the rotation (3, 3), the mass matrix's rotational rows (3, 9) and the
    bias forces on them (3)."""
    # outer loops: the world acceleration wanted, tilt-limited
    c0, c1, c2 = pid_update(position_params, position_state, ref_position[0] - position[0],
                            ref_position[1] - position[1], ref_position[2] - position[2], False, 0.0, 0.0, 0.0)
    f0, f1, f2 = pid_update(velocity_params, velocity_state, ref_velocity[0] + c0 - velocity[0],
                            ref_velocity[1] + c1 - velocity[1], ref_velocity[2] + c2 - velocity[2], False, 0.0, 0.0, 0.0)
    a0, a1, a2 = ref_acceleration[0] + f0, ref_acceleration[1] + f1, ref_acceleration[2] + f2
    horizontal = hypot(a0, a1)
    gravity = constants[G]
    reach = (gravity + a2) * constants[TILT_SLOPE]
    if horizontal > reach and reach > 0:
        shrink = reach / horizontal
        a0 *= shrink
        a1 *= shrink
    # thrust along body z; the wanted attitude: z along the force, x along the planned yaw
    mass = constants[MASS]
    force0, force1, force2 = mass * (a0 + 0.0), mass * (a1 + 0.0), mass * (a2 + gravity)  # + 0.0: -0.0 becomes 0.0
    thrust = inner3(force0, force1, force2, rotation[0, 2], rotation[1, 2], rotation[2, 2])
    thrust = 0.0 if 0.0 > thrust else thrust  # Python's max(thrust, 0.0)
    size = math.sqrt(inner3(force0, force1, force2, force0, force1, force2))
    d0, d1, d2 = force0 / size, force1 / size, force2 / size
    b0, b1 = math.cos(yaw), math.sin(yaw)
    side0, side1, side2 = d1 * 0.0 - d2 * b1, d2 * b0 - d0 * 0.0, d0 * b1 - d1 * b0
    norm = math.sqrt(inner3(side0, side1, side2, side0, side1, side2))
    side0, side1, side2 = side0 / norm, side1 / norm, side2 / norm
    ahead0, ahead1, ahead2 = side1 * d2 - side2 * d1, side2 * d0 - side0 * d2, side0 * d1 - side1 * d0
    wanted = ((ahead0, side0, d0), (ahead1, side1, d1), (ahead2, side2, d2))
    # Wᵀ·R; Rᵀ·W, the rotation into the body frame, is exactly its transpose (the same products in the same order)
    product = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            product[i, j] = gemm_entry3(wanted[0][i], wanted[1][i], wanted[2][i], rotation[0, j], rotation[1, j],
                                        rotation[2, j])
    g = constants[ATTITUDE_GAIN:ATTITUDE_GAIN + 3]
    # the attitude error ½ vee(WᵀR − RᵀW) drives body-rate commands; the rate loop asks for angular accelerations
    e0 = 0.5 * (product[2, 1] - product[1, 2])
    e1 = 0.5 * (product[0, 2] - product[2, 0])
    e2 = 0.5 * (product[1, 0] - product[0, 1])
    r0, r1, r2 = pid_update(rate_params, rate_state,
                            about_z(product, 0, yaw_rate) - g[0] * e0 - body_rates[0],
                            about_z(product, 1, yaw_rate) - g[1] * e1 - body_rates[1],
                            about_z(product, 2, yaw_rate) - g[2] * e2 - body_rates[2], False, 0.0, 0.0, 0.0)
    # moments through the rotational rows of the whole robot's mass matrix, plus its bias forces
    generalized = np.empty(9)
    generalized[0], generalized[1], generalized[2] = a0, a1, a2
    generalized[3] = about_z(product, 0, yaw_acceleration) + r0
    generalized[4] = about_z(product, 1, yaw_acceleration) + r1
    generalized[5] = about_z(product, 2, yaw_acceleration) + r2
    generalized[6], generalized[7], generalized[8] = arm_acceleration[0], arm_acceleration[1], arm_acceleration[2]
    m0, m1, m2 = gemv_rows9(rotational_mass, generalized)
    return thrust, m0 + bias[0], m1 + bias[1], m2 + bias[2]


@_compiled
def control_tick(position_params, position_state, velocity_params, velocity_state, rate_params, rate_state,
                 uav_constants, arm_params, arm_state, max_torque, compensate_pitch, k_inv, top, alpha, speeds,
                 qpos, qvel, joints, full_mass, qfrc_bias, rotation, noise, q, qd, qdd, ctrl):
    """One control tick of Flight (free joint, then the three arm joints in qvel): the rotors' w² and the arm's
    torques into ctrl, the rotor speeds after the motor lag into `speeds`; returns whether the mixer clamped.
    noise: added to the position fed back where noise[3] is nonzero."""
    if noise[3] != 0.0:
        position = (qpos[0] + noise[0], qpos[1] + noise[1], qpos[2] + noise[2])
    else:
        position = (qpos[0], qpos[1], qpos[2])
    joint_ref0, joint_rate_ref0 = q[4], qd[4]
    if compensate_pitch:  # the joints are pitch axes: the arm can undo the body's pitch
        sine = rotation[2, 0]
        sine = sine if sine < 1.0 else 1.0  # as Python's max(-1.0, min(1.0, sine)) picks
        sine = sine if sine > -1.0 else -1.0
        body_pitch = -math.asin(sine)  # nose down is positive, like q
        joint_ref0 -= body_pitch
        joint_rate_ref0 -= qvel[4]
    torques, joint_acceleration = arm_torques(
        arm_params, arm_state, max_torque, (qpos[joints[0]], qpos[joints[1]], qpos[joints[2]]),
        (qvel[6], qvel[7], qvel[8]), (joint_ref0, q[5], q[6]), (joint_rate_ref0, qd[5], qd[6]), (qdd[4], qdd[5], qdd[6]),
        full_mass[6:9, 6:9], qfrc_bias[6:9],
    )
    thrust, m0, m1, m2 = uav_wrench(
        position_params, position_state, velocity_params, velocity_state, rate_params, rate_state, uav_constants,
        position, (qvel[0], qvel[1], qvel[2]), rotation, (qvel[3], qvel[4], qvel[5]), (q[0], q[1], q[2]),
        (qd[0], qd[1], qd[2]), (qdd[0], qdd[1], qdd[2]), q[3], qd[3], qdd[3], full_mass[3:6], qfrc_bias[3:6],
        joint_acceleration,
    )
    commanded, saturated = mix(k_inv, top, thrust, m0, m1, m2)
    lag(speeds, alpha, commanded[0], commanded[1], commanded[2], commanded[3])
    for k in range(4):
        ctrl[k] = speeds[k] * speeds[k]
    ctrl[4], ctrl[5], ctrl[6] = torques
    return saturated
