"""joint_node's parameters as tables of :class:`~.node_parameters.ParameterSpec` (no ROS):
node-wide (:data:`JOINT_NODE_PARAMETERS`), per joint (:data:`JOINT_PARAMETERS`, under
``<joint>.``) and per muscle (:data:`JOINT_MUSCLE_PARAMETERS`, ``<joint>.<muscle>.``); the
node-wide ones it shares with model_node are model_node's rows.
"""

from __future__ import annotations

from .node_parameters import (
    JOINT_STATE_FIELDS,
    ParameterSpec,
    PRESSURE_INPUTS,
    read_only,
    SPECS,
)

#: joint_node's parameters (:mod:`~pma_model_ros.core.files.joint_file`): node-wide, then per joint
#: (:data:`JOINT_PARAMETERS`, under ``<joint>.``), then per muscle
#: (:data:`JOINT_MUSCLE_PARAMETERS`, ``<joint>.<muscle>.``).  All read-only: joint_node reads them
#: at start-up.
JOINT_NODE_PARAMETERS: tuple[ParameterSpec, ...] = read_only(
    ParameterSpec(
        'joints',
        'string[]',
        None,
        'names of the joints, each with its parameters under `<joint>.`',
    ),
    ParameterSpec(
        'config_dir',
        'string',
        '',
        "directory of relative muscle `file`s (empty: the joint file's, the --params-file with "
        "`joints:`; joints given without a file: the package's shipped `config/`)",
    ),
    SPECS['ambient_pressure'],
    SPECS['pressure_reference'],
    SPECS['max_input_age'],
    ParameterSpec(
        'pressure_input',
        'string',
        'per_muscle',
        "where the muscles' pressures come from: `per_muscle` (each muscle's `<muscle>/pressure`, "
        'FluidPressure) or `joint_state` (one `muscle_pressures` JointState, an entry per muscle '
        "by its name, as ros2_control's joint_state_broadcaster publishes state interfaces)",
        choices=PRESSURE_INPUTS,
    ),
    ParameterSpec(
        'pressure_field',
        'string',
        'position',
        '`pressure_input: joint_state`: the JointState array that holds the pressures (Pa, as '
        "`pressure_reference`; joint_state_broadcaster's `map_interface_to_joint_state`, e.g. "
        '`position: pressure`)',
        choices=JOINT_STATE_FIELDS,
    ),
    ParameterSpec(
        'forward_command_topic',
        'string',
        '',
        "topic of every muscle's pressure command as one std_msgs/Float64MultiArray per "
        "torque command, in `forward_command_order` (what ros2_control's "
        'forward_command_controller takes on `<controller>/commands`); empty: none',
    ),
    ParameterSpec(
        'forward_command_order',
        'string[]',
        [],
        "the muscles of the `forward_command_topic` array, in order (the controller's `joints`; "
        "some or all of this node's muscles, each once); empty: every joint's muscles, joint by "
        'joint, the one that shortens for positive θ first',
    ),
)
JOINT_PARAMETERS: tuple[ParameterSpec, ...] = read_only(
    ParameterSpec(
        'radius',
        'double[]',
        None,
        'lever arm r(θ) = Σ radius[k] θ^k (one entry: pulley radius)',
        'm',
    ),
    ParameterSpec('limits', 'double[]', None, '[min, max] joint angle', 'rad'),
    ParameterSpec('muscles', 'string[]', None, "the two muscles' names (topic namespaces)"),
    ParameterSpec(
        'positive',
        'string',
        None,
        'the muscle that shortens for positive θ (REP-103: counter-clockwise)',
    ),
    ParameterSpec(
        'cocontraction',
        'double',
        100e3,
        'co-contraction level of torque commands until a '
        '`cocontraction_command` or `stiffness_command` arrives',
        'Pa gauge',
        (0.0, 1e7),
    ),
    ParameterSpec(
        'cocontraction_mode',
        'string',
        'min',
        'what the level is: `min` (the lower pressure) or `sum` (the pressure sum)',
        choices=('min', 'sum'),
    ),
    ParameterSpec(
        'hardware_id',
        'string',
        '',
        "the device: `hardware_id` of the joint's /diagnostics status (empty: "
        '`/<namespace>/joint_node/<joint>`, unique per node)',
    ),
)
JOINT_MUSCLE_PARAMETERS: tuple[ParameterSpec, ...] = read_only(
    ParameterSpec(
        'file',
        'string',
        '',
        "single-muscle parameter file (empty: the muscle's parameters inline, "
        'as in that file, under `<joint>.<muscle>.`)',
    ),
    ParameterSpec(
        'length_at_zero', 'double', None, "the muscle's length at θ = 0", 'm', (0.0, 10.0)
    ),
)
