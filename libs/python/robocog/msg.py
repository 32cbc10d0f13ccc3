"""Every robocog message type as a Python dataclass.

Generated from the Rust message types by `robocog interface python`: do not edit. The suite
checks that this file is what the generator writes; after changing a message type, write it
again with `robocog interface python > libs/python/robocog/msg.py`.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Literal, Union


AgentAction = Literal["Status", "Start", "Stop"]

@dataclasses.dataclass
class AgentChild:
    component: str = ""
    generation: int = 0
    pid: int = 0

@dataclasses.dataclass
class Time:
    sec: int = 0
    nanosec: int = 0

@dataclasses.dataclass
class Header:
    stamp: Time = dataclasses.field(default_factory=Time)
    frame_id: str = ""

AgentEventKind = Literal["Stdout", "Stderr", "Exited"]

@dataclasses.dataclass
class AgentEvent:
    header: Header = dataclasses.field(default_factory=Header)
    launch_id: str = ""
    machine: str = ""
    component: str = ""
    generation: int = 0
    kind: AgentEventKind = "Stdout"
    line: str = ""
    wait_status: int = 0

@dataclasses.dataclass
class AgentReply:
    header: Header = dataclasses.field(default_factory=Header)
    machine: str = ""
    pid: int = 0
    wait_status: int = 0
    running: list[AgentChild] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class EnvVar:
    name: str = ""
    value: str = ""

@dataclasses.dataclass
class AgentRequest:
    header: Header = dataclasses.field(default_factory=Header)
    launch_id: str = ""
    graph: str = ""
    action: AgentAction = "Status"
    component: str = ""
    generation: int = 0
    binary: str = ""
    dir: str = ""
    args: list[str] = dataclasses.field(default_factory=list)
    env: list[EnvVar] = dataclasses.field(default_factory=list)
    stop_timeout_ms: int = 0

@dataclasses.dataclass
class Answer:
    header: Header = dataclasses.field(default_factory=Header)
    yes: bool = False

AttrKind = Literal["Bool", "Int", "Float", "Text", "Vec3"]

@dataclasses.dataclass
class Vector3:
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0

@dataclasses.dataclass
class AttrValue:
    kind: AttrKind = "Bool"
    bool_value: bool = False
    int_value: int = 0
    float_value: float = 0.0
    text_value: str = ""
    vec3_value: Vector3 = dataclasses.field(default_factory=Vector3)

@dataclasses.dataclass
class Attribute:
    node: str = ""
    key: str = ""
    value: AttrValue = dataclasses.field(default_factory=AttrValue)

@dataclasses.dataclass
class AudioChunk:
    header: Header = dataclasses.field(default_factory=Header)
    sample_rate_hz: int = 0
    channels: int = 0
    pcm_s16le: bytes = b""

BallEventKind = Literal["detected", "out_of_view", "lost", "detection_timed_out"]

BallTrackState = Literal["waiting", "detecting", "tracking"]

@dataclasses.dataclass
class BallEvent:
    header: Header = dataclasses.field(default_factory=Header)
    frame_seq: int = 0
    kind: BallEventKind = "detected"
    state: BallTrackState = "waiting"

@dataclasses.dataclass
class BallTarget:
    header: Header = dataclasses.field(default_factory=Header)
    active: bool = False
    hue_deg: float = 0.0
    saturation: float = 0.0
    diameter_m: float = 0.0

@dataclasses.dataclass
class PixelWindow:
    x: int = 0
    y: int = 0
    width: int = 0
    height: int = 0

@dataclasses.dataclass
class Point:
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0

@dataclasses.dataclass
class BallTrack:
    header: Header = dataclasses.field(default_factory=Header)
    frame_seq: int = 0
    state: BallTrackState = "waiting"
    found: bool = False
    window: PixelWindow = dataclasses.field(default_factory=PixelWindow)
    centre_px: list[float] = dataclasses.field(default_factory=lambda: [0.0 for _ in range(2)])
    has_centre_m: bool = False
    centre_m: Point = dataclasses.field(default_factory=Point)
    diameter_m: float = 0.0
    confidence: float = 0.0
    has_centre_world: bool = False
    centre_world_m: Point = dataclasses.field(default_factory=Point)
    centre_robot_m: Point = dataclasses.field(default_factory=Point)

@dataclasses.dataclass
class BallTruth:
    header: Header = dataclasses.field(default_factory=Header)
    frame_seq: int = 0
    centre_m: Point = dataclasses.field(default_factory=Point)
    centre_world_m: Point = dataclasses.field(default_factory=Point)
    diameter_m: float = 0.0
    in_view: bool = False

@dataclasses.dataclass
class BodyPart:
    name: str = ""
    robot: str = ""
    base_frame: str = ""
    tip_frame: str = ""
    reach_m: float = 0.0

@dataclasses.dataclass
class CameraIntrinsics:
    name: str = ""
    frame: str = ""
    width: int = 0
    height: int = 0
    fx: float = 0.0
    fy: float = 0.0
    cx: float = 0.0
    cy: float = 0.0
    min_range_m: float = 0.0
    max_range_m: float = 0.0

@dataclasses.dataclass
class Camera:
    pinhole: bool = False
    intrinsics: CameraIntrinsics = dataclasses.field(default_factory=CameraIntrinsics)

@dataclasses.dataclass
class CameraStatus:
    header: Header = dataclasses.field(default_factory=Header)
    driver: str = ""
    streaming: bool = False
    detail: str = ""
    frames: int = 0
    losses: int = 0

ChangeEventKind = Literal["NodeAdded", "NodeRemoved", "Reparented", "JointSet", "PoseSet", "AttributeSet", "BodyPartDeclared", "Restored"]

EdgeKind = Literal["Fixed", "Free", "Joint"]

@dataclasses.dataclass
class Quaternion:
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    w: float = 1.0

@dataclasses.dataclass
class Transform:
    translation: Vector3 = dataclasses.field(default_factory=Vector3)
    rotation: Quaternion = dataclasses.field(default_factory=Quaternion)

JointKind = Literal["revolute", "continuous", "prismatic", "fixed"]

@dataclasses.dataclass
class JointLimits:
    lower: float = 0.0
    upper: float = 0.0
    velocity: float = 0.0
    effort: float = 0.0

@dataclasses.dataclass
class Edge:
    kind: EdgeKind = "Fixed"
    transform: Transform = dataclasses.field(default_factory=Transform)
    joint: str = ""
    joint_kind: JointKind = "revolute"
    axis: Vector3 = dataclasses.field(default_factory=Vector3)
    limits: JointLimits = dataclasses.field(default_factory=JointLimits)
    value: float = 0.0

@dataclasses.dataclass
class KeyValue:
    key: str = ""
    value: AttrValue = dataclasses.field(default_factory=AttrValue)

ShapeKind = Literal["Box", "Cylinder", "Capsule", "Sphere", "Mesh"]

@dataclasses.dataclass
class Shape:
    kind: ShapeKind = "Box"
    size_m: Vector3 = dataclasses.field(default_factory=Vector3)
    radius_m: float = 0.0
    length_m: float = 0.0
    filename: str = ""

@dataclasses.dataclass
class CollisionShape:
    origin: Transform = dataclasses.field(default_factory=Transform)
    shape: Shape = dataclasses.field(default_factory=Shape)

@dataclasses.dataclass
class NodeSpec:
    name: str = ""
    node_type: str = ""
    parent: str = ""
    edge: Edge = dataclasses.field(default_factory=Edge)
    attributes: list[KeyValue] = dataclasses.field(default_factory=list)
    camera: Camera = dataclasses.field(default_factory=Camera)
    collision: list[CollisionShape] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class ChangeEvent:
    kind: ChangeEventKind = "NodeAdded"
    stamp_ns: int = 0
    spec: list[NodeSpec] = dataclasses.field(default_factory=list)
    name: str = ""
    new_parent: str = ""
    pose: Transform = dataclasses.field(default_factory=Transform)
    joint: str = ""
    value: float = 0.0
    node: str = ""
    key: str = ""
    attribute: list[AttrValue] = dataclasses.field(default_factory=list)
    part: list[BodyPart] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class ClockTime:
    header: Header = dataclasses.field(default_factory=Header)
    time_ns: int = 0

NaoBody = Literal["Keep", "GoToPosition", "Dribble", "GoToBallAndDribble", "Kick", "Spazza", "Pass", "AskForTheBall", "Turn", "SearchTheBall", "Stop"]

NaoHead = Literal["Keep", "LookAtTheBall", "LookForward", "LookLeft", "LookRight", "Scan"]

NaoStrategy = Literal["Default", "Passages"]

@dataclasses.dataclass
class FieldPoint:
    x_mm: float = 0.0
    y_mm: float = 0.0

@dataclasses.dataclass
class NaoCommand:
    header: Header = dataclasses.field(default_factory=Header)
    body: NaoBody = "Keep"
    head: NaoHead = "Keep"
    strategy: NaoStrategy = "Default"
    target: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    source: str = ""

@dataclasses.dataclass
class CoachRequest:
    header: Header = dataclasses.field(default_factory=Header)
    command: NaoCommand = dataclasses.field(default_factory=NaoCommand)
    aimed: bool = False
    aim: FieldPoint = dataclasses.field(default_factory=FieldPoint)

@dataclasses.dataclass
class CoachStatus:
    header: Header = dataclasses.field(default_factory=Header)
    state: str = ""
    game_state: int = 0
    game_known: bool = False
    link_up: bool = False
    fallen: bool = False
    penalised: bool = False
    last_command: NaoCommand = dataclasses.field(default_factory=NaoCommand)
    has_last: bool = False
    last_done: bool = False
    pending: NaoCommand = dataclasses.field(default_factory=NaoCommand)
    has_pending: bool = False
    last_answer: str = ""
    ball_last_seen_s: float = 0.0
    obstacle_last_seen_s: float = 0.0
    obstacles_tracked: int = 0

Command = Literal["None", "Greet", "Play", "TrackBall", "ScanBall", "TouchBall", "YouTouchedIt", "Quit", "Stop", "Yes", "No", "GoToBallAndDribble", "Pass", "Kick", "ClearBall", "LookLeft", "LookRight", "LookAtBall", "GoToPosition", "SearchBall", "Turn", "AskForBall"]

CommandSource = Literal["Voice", "Panel"]

@dataclasses.dataclass
class Configuration:
    header: Header = dataclasses.field(default_factory=Header)
    machine: str = ""
    active: list[str] = dataclasses.field(default_factory=list)
    all_active: list[str] = dataclasses.field(default_factory=list)
    step: int = 0
    mermaid: str = ""

@dataclasses.dataclass
class ConfigurationRequest:
    header: Header = dataclasses.field(default_factory=Header)
    machine: str = ""

@dataclasses.dataclass
class Counter:
    name: str = ""
    value: int = 0

@dataclasses.dataclass
class Counter64:
    header: Header = dataclasses.field(default_factory=Header)
    value: int = 0

@dataclasses.dataclass
class Diagnostics:
    header: Header = dataclasses.field(default_factory=Header)
    component: str = ""
    counters: list[Counter] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class DrChange:
    header: Header = dataclasses.field(default_factory=Header)
    seq: int = 0
    event: ChangeEvent = dataclasses.field(default_factory=ChangeEvent)

@dataclasses.dataclass
class Fact:
    predicate: str = ""
    args: list[str] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class FieldPose:
    x_mm: float = 0.0
    y_mm: float = 0.0
    theta_rad: float = 0.0

@dataclasses.dataclass
class FieldTruth:
    header: Header = dataclasses.field(default_factory=Header)
    time_s: float = 0.0
    ball: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    controlled: FieldPose = dataclasses.field(default_factory=FieldPose)
    teammate: FieldPose = dataclasses.field(default_factory=FieldPose)
    controlled_body: str = ""
    last_command: list[float] = dataclasses.field(default_factory=list)
    commands_received: int = 0
    score: int = 0
    passes: int = 0
    game_state: int = 0

@dataclasses.dataclass
class JointChange:
    joint: str = ""
    live: float = 0.0
    fork: float = 0.0

@dataclasses.dataclass
class Moved:
    node: str = ""
    distance_m: float = 0.0

@dataclasses.dataclass
class ForkReply:
    header: Header = dataclasses.field(default_factory=Header)
    became_true: list[Fact] = dataclasses.field(default_factory=list)
    became_false: list[Fact] = dataclasses.field(default_factory=list)
    joints_changed: list[JointChange] = dataclasses.field(default_factory=list)
    moved: list[Moved] = dataclasses.field(default_factory=list)
    rejected: list[str] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class JointUpdate:
    joint: str = ""
    value: float = 0.0

@dataclasses.dataclass
class PoseUpdate:
    node: str = ""
    pose: Transform = dataclasses.field(default_factory=Transform)

StructuralChangeKind = Literal["AddNode", "RemoveNode", "Reparent"]

@dataclasses.dataclass
class StructuralChange:
    kind: StructuralChangeKind = "AddNode"
    node: list[NodeSpec] = dataclasses.field(default_factory=list)
    name: str = ""
    new_parent: str = ""
    pose: Transform = dataclasses.field(default_factory=Transform)

@dataclasses.dataclass
class ForkRequest:
    header: Header = dataclasses.field(default_factory=Header)
    joints: list[JointUpdate] = dataclasses.field(default_factory=list)
    poses: list[PoseUpdate] = dataclasses.field(default_factory=list)
    attributes: list[Attribute] = dataclasses.field(default_factory=list)
    changes: list[StructuralChange] = dataclasses.field(default_factory=list)

Game = Literal["Touch", "Coach"]

@dataclasses.dataclass
class GameCommand:
    header: Header = dataclasses.field(default_factory=Header)
    game: Game = "Touch"
    command: Command = "None"
    source: CommandSource = "Voice"
    text: str = ""
    confidence: float = 0.0
    confirmed: bool = False

@dataclasses.dataclass
class GameLog:
    header: Header = dataclasses.field(default_factory=Header)
    machine: str = ""
    kind: str = ""
    text: str = ""
    distance_m: float = 0.0

@dataclasses.dataclass
class PlayerPenalty:
    penalty: int = 0
    secs_till_unpenalised: int = 0

@dataclasses.dataclass
class TeamStatus:
    team_number: int = 0
    score: int = 0
    message_budget: int = 0
    players: list[PlayerPenalty] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class GameState:
    header: Header = dataclasses.field(default_factory=Header)
    state: int = 0
    set_play: int = 0
    game_phase: int = 0
    first_half: bool = False
    kicking_team: int = 0
    secs_remaining: int = 0
    secondary_time: int = 0
    our_team_found: bool = False
    our_team: TeamStatus = dataclasses.field(default_factory=TeamStatus)
    opponent: TeamStatus = dataclasses.field(default_factory=TeamStatus)

@dataclasses.dataclass
class GetNodeRequest:
    header: Header = dataclasses.field(default_factory=Header)
    name: str = ""

JointMode = Literal["position", "velocity"]

@dataclasses.dataclass
class JointTarget:
    joint: str = ""
    mode: JointMode = "position"
    position: float = 0.0
    max_speed: float = 0.0
    velocity: float = 0.0

@dataclasses.dataclass
class JointGoal:
    header: Header = dataclasses.field(default_factory=Header)
    client: str = ""
    priority: int = 0
    targets: list[JointTarget] = dataclasses.field(default_factory=list)
    release: bool = False

JointRefusal = Literal["none", "unknown_joint", "below_lower_limit", "above_upper_limit", "above_max_velocity", "invalid_value", "owned", "driver"]

@dataclasses.dataclass
class JointGoalReply:
    header: Header = dataclasses.field(default_factory=Header)
    accepted: bool = False
    refusal: JointRefusal = "none"
    joint: str = ""
    limit: float = 0.0
    requested: float = 0.0
    owner: str = ""
    detail: str = ""
    preempted: list[str] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class JointState:
    header: Header = dataclasses.field(default_factory=Header)
    name: list[str] = dataclasses.field(default_factory=list)
    position: list[float] = dataclasses.field(default_factory=list)
    velocity: list[float] = dataclasses.field(default_factory=list)
    effort: list[float] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class JointStates:
    joint_state: JointState = dataclasses.field(default_factory=JointState)
    driver: str = ""
    has_effort: list[bool] = dataclasses.field(default_factory=list)
    owner: list[str] = dataclasses.field(default_factory=list)

LinkChange = Literal["Established", "RobotNotResponding", "Restored"]

@dataclasses.dataclass
class ListeningDirection:
    header: Header = dataclasses.field(default_factory=Header)
    beam_azimuth_rad: float = 0.0
    listening_to: str = ""
    located: bool = False
    talker_azimuth_rad: float = 0.0
    elsewhere: bool = False

@dataclasses.dataclass
class NaoLinkEvent:
    header: Header = dataclasses.field(default_factory=Header)
    player_number: int = 0
    change: LinkChange = "Established"
    silent_for_s: float = 0.0

@dataclasses.dataclass
class NaoObstacle:
    kind: int = 0
    center: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    last_seen_ms: int = 0

@dataclasses.dataclass
class NaoLocalModel:
    header: Header = dataclasses.field(default_factory=Header)
    player_number: int = 0
    team_number: int = 0
    fallen: bool = False
    pose: FieldPose = dataclasses.field(default_factory=FieldPose)
    ball_age_s: float = 0.0
    ball: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    role: int = 0
    obstacles_seen: int = 0
    obstacles: list[NaoObstacle] = dataclasses.field(default_factory=list)
    message_budget: int = 0
    secs_remaining: int = 0
    arm_contact: list[bool] = dataclasses.field(default_factory=lambda: [False for _ in range(2)])
    arm_push_direction: list[int] = dataclasses.field(default_factory=lambda: [0 for _ in range(2)])
    arm_last_contact_ms: list[int] = dataclasses.field(default_factory=lambda: [0 for _ in range(2)])
    time_since_whistle_ms: int = 0
    whistle: int = 0
    team_ball: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    team_ball_velocity: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    battery: float = 0.0
    cpu_temperature_c: float = 0.0
    referee_gesture: int = 0

@dataclasses.dataclass
class TeamRobot:
    player_number: int = 0
    role: int = 0
    pose: FieldPose = dataclasses.field(default_factory=FieldPose)
    fallen: bool = False
    age_s: float = 0.0

@dataclasses.dataclass
class TrackedObstacle:
    id: int = 0
    kind: int = 0
    center: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    age_s: float = 0.0
    observations: int = 0

@dataclasses.dataclass
class NaoWorldModel:
    header: Header = dataclasses.field(default_factory=Header)
    robots: list[TeamRobot] = dataclasses.field(default_factory=list)
    ball_known: bool = False
    ball: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    ball_velocity: FieldPoint = dataclasses.field(default_factory=FieldPoint)
    ball_age_s: float = 0.0
    ball_sigma_mm: float = 0.0
    ball_confidence: float = 0.0
    obstacles: list[TrackedObstacle] = dataclasses.field(default_factory=list)
    striker_known: bool = False
    autonomous_is_striker: bool = False
    confidence: float = 0.0

@dataclasses.dataclass
class NodeInfo:
    header: Header = dataclasses.field(default_factory=Header)
    name: str = ""
    node_type: str = ""
    parent: str = ""
    children: list[str] = dataclasses.field(default_factory=list)
    edge: str = ""
    joint: str = ""
    joint_value: float = 0.0
    pose: Transform = dataclasses.field(default_factory=Transform)
    attributes: list[Attribute] = dataclasses.field(default_factory=list)
    spec: NodeSpec = dataclasses.field(default_factory=NodeSpec)

@dataclasses.dataclass
class PddlReply:
    header: Header = dataclasses.field(default_factory=Header)
    problem: str = ""

@dataclasses.dataclass
class PddlRequest:
    header: Header = dataclasses.field(default_factory=Header)
    problem_name: str = ""
    goal: list[Fact] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class Ping:
    header: Header = dataclasses.field(default_factory=Header)
    sent_ns: int = 0
    data: bytes = b""

@dataclasses.dataclass
class PredicateReply:
    header: Header = dataclasses.field(default_factory=Header)
    holds: bool = False
    facts: list[Fact] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class PredicateRequest:
    header: Header = dataclasses.field(default_factory=Header)
    predicate: str = ""
    args: list[str] = dataclasses.field(default_factory=list)
    stamp_ns: int = 0

Priority = Literal["Low", "Normal", "High", "Urgent"]

@dataclasses.dataclass
class ProposeReply:
    header: Header = dataclasses.field(default_factory=Header)
    accepted: bool = False
    reason_code: str = ""
    reason: str = ""
    seq: int = 0

@dataclasses.dataclass
class ProposeRequest:
    header: Header = dataclasses.field(default_factory=Header)
    change: StructuralChange = dataclasses.field(default_factory=StructuralChange)

ReachKind = Literal["position", "pose", "gaze"]

@dataclasses.dataclass
class ReachGoal:
    header: Header = dataclasses.field(default_factory=Header)
    id: int = 0
    client: str = ""
    active: bool = False
    body_part: str = ""
    kind: ReachKind = "position"
    frame: str = ""
    position_m: Point = dataclasses.field(default_factory=Point)
    orientation_xyzw: Quaternion = dataclasses.field(default_factory=Quaternion)
    tolerance_m: float = 0.0
    follow: bool = False
    min_duration_s: float = 0.0

ReachState = Literal["moving", "reached", "unreachable", "cancelled", "failed"]

@dataclasses.dataclass
class ReachStatus:
    header: Header = dataclasses.field(default_factory=Header)
    id: int = 0
    body_part: str = ""
    state: ReachState = "moving"
    residual_m: float = 0.0
    distance_m: float = 0.0
    target_world_m: Point = dataclasses.field(default_factory=Point)
    tip_world_m: Point = dataclasses.field(default_factory=Point)
    detail: str = ""

@dataclasses.dataclass
class RegionOfInterest:
    x_offset: int = 0
    y_offset: int = 0
    height: int = 0
    width: int = 0
    do_rectify: bool = False

@dataclasses.dataclass
class CameraInfo:
    header: Header = dataclasses.field(default_factory=Header)
    height: int = 0
    width: int = 0
    distortion_model: str = ""
    d: list[float] = dataclasses.field(default_factory=list)
    k: list[float] = dataclasses.field(default_factory=lambda: [0.0 for _ in range(9)])
    r: list[float] = dataclasses.field(default_factory=lambda: [0.0 for _ in range(9)])
    p: list[float] = dataclasses.field(default_factory=lambda: [0.0 for _ in range(12)])
    binning_x: int = 0
    binning_y: int = 0
    roi: RegionOfInterest = dataclasses.field(default_factory=RegionOfInterest)

@dataclasses.dataclass
class Image:
    header: Header = dataclasses.field(default_factory=Header)
    height: int = 0
    width: int = 0
    encoding: str = ""
    is_bigendian: int = 0
    step: int = 0
    data: bytes = b""

@dataclasses.dataclass
class RgbdFrame:
    header: Header = dataclasses.field(default_factory=Header)
    camera_info: CameraInfo = dataclasses.field(default_factory=CameraInfo)
    rgb: Image = dataclasses.field(default_factory=Image)
    depth: Image = dataclasses.field(default_factory=Image)

@dataclasses.dataclass
class SayRequest:
    header: Header = dataclasses.field(default_factory=Header)
    id: int = 0
    text: str = ""
    priority: Priority = "Low"

@dataclasses.dataclass
class SimBall:
    header: Header = dataclasses.field(default_factory=Header)
    present: bool = False
    centre_world_m: Point = dataclasses.field(default_factory=Point)
    velocity_world_mps: Vector3 = dataclasses.field(default_factory=Vector3)
    diameter_m: float = 0.0
    hue_deg: float = 0.0
    saturation: float = 0.0
    held: bool = False

@dataclasses.dataclass
class Snapshot:
    stamp_ns: int = 0
    nodes: list[NodeSpec] = dataclasses.field(default_factory=list)
    body_parts: list[BodyPart] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class SnapshotData:
    header: Header = dataclasses.field(default_factory=Header)
    snapshot: Snapshot = dataclasses.field(default_factory=Snapshot)
    last_seq: int = 0

@dataclasses.dataclass
class SnapshotRequest:
    header: Header = dataclasses.field(default_factory=Header)

SpeakingState = Literal["Queued", "Started", "Finished", "Interrupted", "Dropped", "Failed"]

@dataclasses.dataclass
class SpeakingEvent:
    header: Header = dataclasses.field(default_factory=Header)
    id: int = 0
    text: str = ""
    state: SpeakingState = "Queued"
    duration_s: float = 0.0
    detail: str = ""

@dataclasses.dataclass
class StateTransition:
    header: Header = dataclasses.field(default_factory=Header)
    machine: str = ""
    event: str = ""
    exited: list[str] = dataclasses.field(default_factory=list)
    entered: list[str] = dataclasses.field(default_factory=list)
    active: list[str] = dataclasses.field(default_factory=list)
    step: int = 0

@dataclasses.dataclass
class TalkKey:
    header: Header = dataclasses.field(default_factory=Header)
    held: bool = False
    source: str = ""

@dataclasses.dataclass
class Text:
    header: Header = dataclasses.field(default_factory=Header)
    text: str = ""

@dataclasses.dataclass
class TransformReply:
    header: Header = dataclasses.field(default_factory=Header)
    target: str = ""
    source: str = ""
    stamp_ns: int = 0
    transform: Transform = dataclasses.field(default_factory=Transform)

@dataclasses.dataclass
class TransformRequest:
    header: Header = dataclasses.field(default_factory=Header)
    target: str = ""
    source: str = ""
    stamp_ns: int = 0

@dataclasses.dataclass
class UpdateReply:
    header: Header = dataclasses.field(default_factory=Header)
    applied: int = 0
    last_seq: int = 0

@dataclasses.dataclass
class UpdateRequest:
    header: Header = dataclasses.field(default_factory=Header)
    attributes: list[Attribute] = dataclasses.field(default_factory=list)
    poses: list[PoseUpdate] = dataclasses.field(default_factory=list)
    joints: list[JointUpdate] = dataclasses.field(default_factory=list)

@dataclasses.dataclass
class Utterance:
    header: Header = dataclasses.field(default_factory=Header)
    game: Game = "Touch"
    text: str = ""
    confidence: float = 0.0
    command: Command = "None"
    in_grammar: bool = False
    stream_start_s: float = 0.0
    stream_end_s: float = 0.0
    decode_duration_s: float = 0.0
    latency_s: float = 0.0

VoiceState = Literal["Started", "Ended", "Dropped"]

@dataclasses.dataclass
class VoiceActivity:
    header: Header = dataclasses.field(default_factory=Header)
    state: VoiceState = "Started"
    stream_s: float = 0.0

# Every message type by its name on the bus.
TYPES: dict[str, type] = {
    "robocog.Answer": Answer,
    "robocog.AudioChunk": AudioChunk,
    "robocog.BallEvent": BallEvent,
    "robocog.BallTarget": BallTarget,
    "robocog.BallTrack": BallTrack,
    "robocog.CameraStatus": CameraStatus,
    "robocog.ClockTime": ClockTime,
    "robocog.Counter64": Counter64,
    "robocog.Diagnostics": Diagnostics,
    "robocog.GameCommand": GameCommand,
    "robocog.Ping": Ping,
    "robocog.RgbdFrame": RgbdFrame,
    "robocog.Text": Text,
    "robocog.agent.Event": AgentEvent,
    "robocog.agent.Reply": AgentReply,
    "robocog.agent.Request": AgentRequest,
    "robocog.body.JointGoal": JointGoal,
    "robocog.body.JointGoalReply": JointGoalReply,
    "robocog.body.JointStates": JointStates,
    "robocog.body.ReachGoal": ReachGoal,
    "robocog.body.ReachStatus": ReachStatus,
    "robocog.dr.DrChange": DrChange,
    "robocog.dr.ForkReply": ForkReply,
    "robocog.dr.ForkRequest": ForkRequest,
    "robocog.dr.GetNodeRequest": GetNodeRequest,
    "robocog.dr.NodeInfo": NodeInfo,
    "robocog.dr.PddlReply": PddlReply,
    "robocog.dr.PddlRequest": PddlRequest,
    "robocog.dr.PredicateReply": PredicateReply,
    "robocog.dr.PredicateRequest": PredicateRequest,
    "robocog.dr.ProposeReply": ProposeReply,
    "robocog.dr.ProposeRequest": ProposeRequest,
    "robocog.dr.SnapshotData": SnapshotData,
    "robocog.dr.SnapshotRequest": SnapshotRequest,
    "robocog.dr.TransformReply": TransformReply,
    "robocog.dr.TransformRequest": TransformRequest,
    "robocog.dr.UpdateReply": UpdateReply,
    "robocog.dr.UpdateRequest": UpdateRequest,
    "robocog.executive.Configuration": Configuration,
    "robocog.executive.ConfigurationRequest": ConfigurationRequest,
    "robocog.executive.GameLog": GameLog,
    "robocog.executive.StateTransition": StateTransition,
    "robocog.nao.CoachRequest": CoachRequest,
    "robocog.nao.CoachStatus": CoachStatus,
    "robocog.nao.Command": NaoCommand,
    "robocog.nao.GameState": GameState,
    "robocog.nao.LinkEvent": NaoLinkEvent,
    "robocog.nao.LocalModel": NaoLocalModel,
    "robocog.nao.WorldModel": NaoWorldModel,
    "robocog.sim.Ball": SimBall,
    "robocog.sim.BallTruth": BallTruth,
    "robocog.sim.FieldTruth": FieldTruth,
    "robocog.speech.ListeningDirection": ListeningDirection,
    "robocog.speech.SayRequest": SayRequest,
    "robocog.speech.SpeakingEvent": SpeakingEvent,
    "robocog.speech.TalkKey": TalkKey,
    "robocog.speech.Utterance": Utterance,
    "robocog.speech.VoiceActivity": VoiceActivity,
}

# Every struct by its serde name (the decoder builds them by it).
CLASSES: dict[str, type] = {
    "AgentChild": AgentChild,
    "builtin_interfaces/msg/Time": Time,
    "std_msgs/msg/Header": Header,
    "AgentEvent": AgentEvent,
    "AgentReply": AgentReply,
    "EnvVar": EnvVar,
    "AgentRequest": AgentRequest,
    "Answer": Answer,
    "geometry_msgs/msg/Vector3": Vector3,
    "AttrValue": AttrValue,
    "Attribute": Attribute,
    "AudioChunk": AudioChunk,
    "BallEvent": BallEvent,
    "BallTarget": BallTarget,
    "PixelWindow": PixelWindow,
    "geometry_msgs/msg/Point": Point,
    "BallTrack": BallTrack,
    "BallTruth": BallTruth,
    "BodyPart": BodyPart,
    "CameraIntrinsics": CameraIntrinsics,
    "Camera": Camera,
    "CameraStatus": CameraStatus,
    "geometry_msgs/msg/Quaternion": Quaternion,
    "geometry_msgs/msg/Transform": Transform,
    "JointLimits": JointLimits,
    "Edge": Edge,
    "KeyValue": KeyValue,
    "Shape": Shape,
    "CollisionShape": CollisionShape,
    "NodeSpec": NodeSpec,
    "ChangeEvent": ChangeEvent,
    "ClockTime": ClockTime,
    "FieldPoint": FieldPoint,
    "NaoCommand": NaoCommand,
    "CoachRequest": CoachRequest,
    "CoachStatus": CoachStatus,
    "Configuration": Configuration,
    "ConfigurationRequest": ConfigurationRequest,
    "Counter": Counter,
    "Counter64": Counter64,
    "Diagnostics": Diagnostics,
    "DrChange": DrChange,
    "Fact": Fact,
    "FieldPose": FieldPose,
    "FieldTruth": FieldTruth,
    "JointChange": JointChange,
    "Moved": Moved,
    "ForkReply": ForkReply,
    "JointUpdate": JointUpdate,
    "PoseUpdate": PoseUpdate,
    "StructuralChange": StructuralChange,
    "ForkRequest": ForkRequest,
    "GameCommand": GameCommand,
    "GameLog": GameLog,
    "PlayerPenalty": PlayerPenalty,
    "TeamStatus": TeamStatus,
    "GameState": GameState,
    "GetNodeRequest": GetNodeRequest,
    "JointTarget": JointTarget,
    "JointGoal": JointGoal,
    "JointGoalReply": JointGoalReply,
    "sensor_msgs/msg/JointState": JointState,
    "JointStates": JointStates,
    "ListeningDirection": ListeningDirection,
    "NaoLinkEvent": NaoLinkEvent,
    "NaoObstacle": NaoObstacle,
    "NaoLocalModel": NaoLocalModel,
    "TeamRobot": TeamRobot,
    "TrackedObstacle": TrackedObstacle,
    "NaoWorldModel": NaoWorldModel,
    "NodeInfo": NodeInfo,
    "PddlReply": PddlReply,
    "PddlRequest": PddlRequest,
    "Ping": Ping,
    "PredicateReply": PredicateReply,
    "PredicateRequest": PredicateRequest,
    "ProposeReply": ProposeReply,
    "ProposeRequest": ProposeRequest,
    "ReachGoal": ReachGoal,
    "ReachStatus": ReachStatus,
    "sensor_msgs/msg/RegionOfInterest": RegionOfInterest,
    "sensor_msgs/msg/CameraInfo": CameraInfo,
    "sensor_msgs/msg/Image": Image,
    "RgbdFrame": RgbdFrame,
    "SayRequest": SayRequest,
    "SimBall": SimBall,
    "Snapshot": Snapshot,
    "SnapshotData": SnapshotData,
    "SnapshotRequest": SnapshotRequest,
    "SpeakingEvent": SpeakingEvent,
    "StateTransition": StateTransition,
    "TalkKey": TalkKey,
    "Text": Text,
    "TransformReply": TransformReply,
    "TransformRequest": TransformRequest,
    "UpdateReply": UpdateReply,
    "UpdateRequest": UpdateRequest,
    "Utterance": Utterance,
    "VoiceActivity": VoiceActivity,
}

