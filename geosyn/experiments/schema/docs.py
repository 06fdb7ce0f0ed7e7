"""Units and meanings of the config fields that stand for no library parameter.

A `Section`'s fields that are parameters of its library calls are documented by those
calls' docstrings (`geosyn.experiments.schema.describe`); this table holds the others:
``model name -> field -> (unit, meaning)``. A procedure's ``params`` model is documented
here too, under its class name.
"""

from __future__ import annotations

#: Meaning of every ``type`` field (the discriminator of a list item or section).
TYPE_FIELD = "which kind of item this is (selects its other fields)"

_LABEL = ("", "name of this controller's runs and summary rows (default: its type, numbered)")
_Q_START = ("rad", "(nv,) start configuration")
_STEPS = ("", "integration steps of each geodesic")
_DURATION = ("s", "time of each motion")

FIELD_DOCS: dict[str, dict[str, tuple[str, str]]] = {
    "ExperimentConfig": {
        "name": ("", "name of the experiment (run directories are named after it)"),
        "description": ("", "free text shown in summary.md and `geosyn list`"),
        "kind": ("", "the procedure that runs it (`geosyn list`; general: tracking)"),
        "seed": ("", "seed of every random draw (noise, demonstrations)"),
        "robot": ("", "the robot"),
        "metric": ("", "the metric: kinetic energy plus shaping terms"),
        "scene": ("", "payloads and obstacles of the MuJoCo scene, and whether they collide"),
        "stance": ("", "a floating robot's contact frames held on the floor, their points"),
        "synergies": ("", "synergies of the robot (needed by a combination reference)"),
        "reference": ("", "what the controllers track"),
        "controllers": ("", "the controllers; each one runs the experiment"),
        "disturbances": ("", "pushes, wrenches, payload changes, noise, latency"),
        "simulation": ("", "MuJoCo simulation settings"),
        "outputs": ("", "what a run writes besides results.npz and summaries"),
        "params": ("", "settings of the kind's procedure (`geosyn schema params`)"),
    },
    "RobotConfig": {
        "name": ("", "a built-in robot (`geosyn robots`) or a .urdf/.xml/.mjcf path"),
        "options": ("", "options of load_robot"),
    },
    "RobotOptions": {
        "armature": ("kg m^2", "rotor inertia added to every joint (null: the model's)"),
        "gravity": ("m/s^2", "(3,) gravity vector (null: the model's)"),
        "ee_frame": ("", "end-effector frame (null: the robot's)"),
        "fixed_base": ("", "weld a floating base to the world (null: the robot's own)"),
        "tau_max": (
            "N m",
            "torque limit: one for every joint, or {joint: limit} (null: the file's limits)",
        ),
        "floating_base": ("", "put a URDF's root link on a free flyer (null: fixed)"),
        "default_tau_max": (
            "N m",
            "torque limit of joints the file and tau_max give none (null: the loader's, warned)",
        ),
        "default_v_max": (
            "rad/s",
            "velocity limit of joints the file gives none (null: the loader's default, warned)",
        ),
        "keep_joints": ("", "joints to keep; every other is locked (null: all joints)"),
        "lock_q": ("rad or m", "{joint: position} where locked joints are held (null: 0, clipped)"),
        "damping": ("N m s/rad", "{joint: viscous damping} replacing the file's ({}: none)"),
        "frictionloss": ("N m", "{joint: dry friction} replacing the file's ({}: none)"),
        "capsule_radius": (
            "m",
            "radius of the derived collision capsules (null: the loader's default)",
        ),
        "inertia_check": (
            "",
            "an unphysical URDF inertial: 'error' refuses the file, 'warn' loads it (null: error)",
        ),
    },
    "StanceConfig": {
        "frames": ("", "contact frames held on the floor (feet, soles)"),
        "points": ("m", "(P, 3) contact points in each frame; 1: a point foot, >= 3: a sole"),
        "mu": ("", "friction coefficient of the controllers' cones (below the floor's 1.0)"),
        "f_min": ("N", "smallest normal force per contact point"),
    },
    "SynergyDirection": {
        "base": ("m/s, rad/s", "(6,) base twist of the wish, base frame"),
        "joints": ("rad/s", "joint rates of the wish by joint name (others 0)"),
    },
    "WholeBodyConfig": {"label": _LABEL},
    "MetricConfig": {"terms": ("", "shaping terms added to the kinetic-energy metric")},
    "SceneConfig": {
        "payloads": ("", "rigid payloads welded to links"),
        "obstacles": ("", "obstacles (seen by obstacle terms and the clearance)"),
        "mjcf": ("", "more obstacles: the static geoms of a MuJoCo scene file"),
        "contact": ("", "obstacles collide with the robot in MuJoCo (false: visual only)"),
    },
    "MjcfObstaclesConfig": {
        "file": ("", "the MJCF scene file (a path relative to the config file)"),
        "visual": ("", "also its visual-only geoms (contype and conaffinity 0)"),
    },
    "SphereConfig": {"center": ("m", "(3,) centre"), "radius": ("m", "radius")},
    "BoxConfig": {
        "center": ("m", "(3,) centre"),
        "half_extents": ("m", "(3,) half side lengths"),
        "rpy": ("rad", "roll, pitch, yaw about the world axes, R = Rz Ry Rx"),
    },
    "CapsuleConfig": {
        "p0": ("m", "(3,) first end of the axis"),
        "p1": ("m", "(3,) second end of the axis"),
        "radius": ("m", "radius"),
    },
    "HalfSpaceConfig": {
        "normal": ("", "(3,) outward normal (normalised)"),
        "offset": ("m", "the obstacle is {x : normal . x <= offset}"),
    },
    "PayloadConfig": {
        "frame": ("", "link frame it is welded to (null: the end effector)"),
        "mass": ("kg", "mass"),
        "offset": ("m", "(3,) centre of mass in the frame"),
        "inertia": ("kg m^2", "(3, 3) inertia about the centre of mass (null: a ball)"),
        "radius": ("m", "radius of the ball (inertia and drawing)"),
        "name": ("", "name, for payload_change disturbances"),
    },
    "LoadTermConfig": {"payload": ("", "index into scene.payloads (instead of frame/mass)")},
    "ExplicitSynergies": {"items": ("", "the synergies")},
    "ExplicitSynergy": {
        "q0": ("rad", "(nv,) base configuration"),
        "v0": ("rad/s", "(nv,) initial velocity of the geodesic"),
    },
    "PGASynergies": {
        "q0": ("rad", "(nv,) base of the generated demonstrations"),
        "k": ("", "number of synergies extracted"),
        "n_demos": ("", "number of generated demonstrations"),
        "spread": ("rad/s", "standard deviation of the demonstrations' velocities"),
        "latent": ("", "number of directions the demonstrations vary in"),
    },
    "LogReference": {"q_start": _Q_START, "goal": ("rad", "(nv,) goal configuration")},
    "GoalsReference": {
        "q_start": _Q_START,
        "goals": ("rad", "the goals, each (nv,), reached one after the other"),
        "duration": ("s", "geodesic time of each segment: one value, or one per goal"),
    },
    "PlannedReference": {
        "q_start": _Q_START,
        "goal": ("", "(nv,) goal configuration [rad], or an end-effector goal"),
        "duration": ("s", "time of the path before time scaling"),
        "time_scale": ("", "time scale s > 0 (s > 1 is slower)"),
        "rest_to_rest": ("", "traverse the path with the quintic rest-to-rest time law"),
        "margin": ("m", "clearance the planned path keeps from the obstacles"),
        "nodes": ("", "segments of the planner's collocation"),
        "budget": ("s", "wall-time limit of the planning query"),
    },
    "EndEffectorGoalConfig": {
        "position": ("m", "(3,) world position of the frame's origin"),
        "rpy": ("rad", "(3,) roll-pitch-yaw of the frame (null: position only)"),
        "frame": ("", "frame of the robot (null: its end effector)"),
        "position_tolerance": ("m", "largest distance of the frame from position"),
        "orientation_tolerance": ("rad", "largest rotation angle from rpy"),
        "solutions": ("", "distinct IK solutions planned to (lowest energy kept)"),
    },
    "ComputedTorqueConfig": {"label": _LABEL},
    "RiemannianPDConfig": {"label": _LABEL},
    "QPConfig": {"label": _LABEL},
    "MPCConfig": {"label": _LABEL},
    "OutputsConfig": {
        "plots": ("", "write PNG plots"),
        "csv": ("", "write data/<run>.csv per closed-loop run (named columns)"),
        "parquet": ("", "also write data/<run>.parquet (the CSV's columns; the parquet extra)"),
        "video": ("", "render a video of every motion (also: --video)"),
        "video_format": ("", "video file format"),
    },
    # procedures' params
    "TrackingParams": {"threshold": ("rad", "error norm below which a run has recovered")},
    "PushRecoveryParams": {
        "threshold": ("rad", "error norm below which a run has recovered"),
        "window": ("s", "RMS error is also reported from this long after the push on"),
    },
    "GeodesicVsEuclideanParams": {
        "q0": ("rad", "(2,) start configuration"),
        "q1": ("rad", "(2,) end configuration"),
        "duration": _DURATION,
        "steps": _STEPS,
    },
    "PGAvsPCAParams": {
        "q0": ("rad", "(nv,) base of the generated demonstrations"),
        "n_demos": ("", "number of demonstrations"),
        "spread": ("rad/s", "standard deviation of the demonstrations' velocities"),
        "latent": ("", "number of directions the demonstrations vary in"),
        "k_max": ("", "largest number of synergies compared"),
        "steps": _STEPS,
    },
    "SynergyCombinationsParams": {
        "weights": ("", "weight pairs of the two synergies"),
        "duration": _DURATION,
        "steps": _STEPS,
    },
    "SynergyTransportParams": {
        "bases": ("rad", "base configurations of the synergies, each (nv,)"),
        "q_start": _Q_START,
        "weights": ("", "one weight per synergy"),
        "duration": _DURATION,
        "steps": _STEPS,
    },
    "PickAndPlaceParams": {
        "pick": ("m", "(3,) hand position of the grasp"),
        "via": ("m", "(3,) hand position the carry passes through"),
        "place": ("m", "(3,) hand position of the release"),
        "mass": ("kg", "mass of the carried object"),
        "durations": ("s", "durations of reach, carry to via, carry to place"),
        "dwell": ("s", "time held still at the grasp and at the release"),
        "steps": _STEPS,
        "sample_dt": ("s", "sample period of the reference"),
    },
    "SynergySequenceParams": {
        "targets": ("m", "Cartesian hand goals, each (3,), reached one after the other"),
        "durations": ("s", "duration of each segment: one value, or one per target"),
        "steps": _STEPS,
        "sample_dt": ("s", "sample period of the reference"),
        "settle": ("s", "time simulated after the motion ends"),
    },
}

__all__ = ["FIELD_DOCS", "TYPE_FIELD"]
