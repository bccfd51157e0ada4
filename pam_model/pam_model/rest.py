"""The rig at rest: both valves at the bias voltage beta (MODEL.md section 7), the joint at 0 rad
and both muscles at the pressure that command holds. Every node, tool and simulator that starts
the rig, a plant or a filter from rest takes its default from here (written once)."""

BETA = 5.5                    # V, bias voltage of both valves
REST_COMMAND = (BETA, BETA)   # V, u1, u2: equal co-contraction, the joint rests near 0 rad
REST_PRESSURE = 4.5e5         # Pa abs, each muscle's pressure under REST_COMMAND
REST_STATE = (0.0, 0.0, REST_PRESSURE, REST_PRESSURE)   # psi rad, psi_dot rad/s, P1 Pa, P2 Pa
