"""OdmoConfig: every hyper-parameter of the ODMO model and its training, saved in model.json."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from engine.errors import ConfigError
from engine.model.config_base import ModelConfig

#: Fields added after the first models were saved, with the value that reproduces those models.
_BEFORE_SWITCHES = {
    "exact_end": False,
    "root_relative_poses": False,
    "bone_projection": False,
    "foot_contact": False,
    "w_velocity": 0.0,
    "scheduled_sampling": "one_step",
    "w_skate": 1.0,
    "w_free": 0.0,
    "w_speed": 0.0,
    "speed_error": "absolute",
    "speed_span": 0,
    "spectrum_span": 0,
    "w_spectrum": 0.0,
    "w_free_skate": 0.0,
    "spectrum_legs": True,
    "free_skate_contacts": "data",
    "w_foot_height": 0.0,
    "w_heading": 0.0,
    "w_twist": 0.0,
    "w_coordination": 0.0,
    "coordination_on": "all",
    "root_velocity_input": False,
    "mean_pose_init": False,
    "pose_output": "joints",
    "free_shift": 0,
    "w_start": 0.0,
    "pose_update": "absolute",
    "encoder_reverse": False,
    "w_stance": 0.0,
    "clock_hz": (),
    "code_rhythms": 0,
    "w_rollout": 0.0,
    "step_input": False,
    "w_upper_speed": 0.0,
    "w_foot_twist": 0.0,
    "w_skim": 0.0,
    "w_stand": 0.0,
    "w_floor": 0.0,
}
SCHEDULED_SAMPLING = ("one_step", "free_run")
#: The paper's model in one setting, ``OdmoConfig(n_actions, n_joints, **PAPER)``: every project change off.
PAPER: dict[str, Any] = {"contrastive_pull": 1.0, **_BEFORE_SWITCHES}
TRAIN_PRECISIONS = ("float32", "bfloat16")
SPEED_ERRORS = ("absolute", "log")
FREE_SKATE_CONTACTS = ("data", "own")
COORDINATION_ON = ("all", "legs")
POSE_OUTPUTS = ("joints", "rotations")
POSE_UPDATES = ("absolute", "residual")
MAX_CLOCK_FREQUENCIES = 32


@dataclass
class OdmoConfig(ModelConfig):
    """Sizes, loss weights and training schedule of one ODMO model.

    The defaults follow the paper (D = 20, T = 60, LSTM 64 / 128, every loss weight 1, α = 5,
    σ² = 0.05 as a variance, Adam 1e-3, epochs of 2,048 class-balanced windows, teacher forcing
    decaying linearly 1 → 0.3) except the batch (128 windows, the reference uses 512) and the number of
    epochs, which are sized for a CPU. Two changes to the paper's model, each switchable:
    ``exact_end`` shears the generated root path so that it ends exactly at r_e (the paper only
    conditions on it), and ``root_relative_poses`` has the pose decoder emit and read back joints
    relative to the generated trajectory (the paper's emits absolute xyz, which drifts free-running).
    ``contrastive_pull`` scales the same-action pull of the contrastive term (1, the paper's, by default).
    ``train_precision`` "bfloat16" runs the training forward pass under bfloat16 autocast (weights, the
    optimiser and every decode stay float32); it is faster on CPUs with bfloat16 instructions.
    ``bone_projection`` puts the decoded joints onto the skeleton's bone lengths (``BoneProjection``;
    the reconstruction loss is taken on the projected joints, ``w_raw`` weights it on the raw ones the
    decoder reads back). ``foot_contact`` adds a head predicting which ``foot_joints`` are planted
    (labels from the data, resting heights ``foot_heights`` above the floor), a contact loss
    (``w_contact``: cross-entropy; ``w_skate``: the squared speed of generated feet where the data's are
    planted) and the decode-time clean-up that pins planted feet. ``w_velocity`` weights an L2 loss on
    frame-to-frame joint velocities. ``w_free`` weights the reconstruction loss of a free-running decode
    of the same codes (the decoder as it runs at sampling time, trained through its own poses; with
    ``free_span`` > 1 on the mean pose of each run of that many frames, leaving the motion within a run to
    the phase-free terms; with ``free_shift`` > 0 on root-relative poses at the time shift of at most that
    many frames that fits each window best, so a decode out of phase with the data keeps its amplitude),
    ``w_start`` the squared error of that decode's first ``start_frames`` root-relative poses (the decoder
    keeps a gait it is started in, so the code must carry where in its cycle the motion starts),
    ``w_rollout`` the squared error of ``rollout_frames`` root-relative poses decoded free-running from a
    random frame on, after teacher-forced ones before it (``OdmoModel.rollout``: the decoder learns to
    continue a motion whose phase it has seen; on the decode from the first frame, whose phase drifts,
    L2 rewards damping) and
    ``w_speed`` the squared error of that decode's per-window mean joint speeds (which, unlike an L2
    loss on positions, does not reward a still mean pose when the phase is uncertain); all three are off by
    default, measured in the README ("Where the model differs from the paper"). The skate and speed
    terms are in m²/s²; ``speed_error`` "log" compares log speeds instead (relative errors: a slow
    wave's hand weighs as much as a run's feet); ``speed_span`` > 0 compares them over each run of that
    many frames instead of the whole window (a burst that then stops no longer passes);
    ``w_upper_speed`` weights the same error per run of ``upper_speed_span`` frames on the joints outside
    the legs only (``upper_joints``: a wave that stops after a burst fails it, while the legs keep the
    window's measure, whose spans turned walks into runs, README). ``w_spectrum``
    weights the squared error of that decode's log amplitude spectra per joint (how much it moves at
    each rhythm, phase-free: a slow raise and a quick wave of one mean speed differ there), over each
    run of ``spectrum_span`` frames if > 0.
    ``w_free_skate`` weights the skate loss on that decode's feet (the motion sampling shows;
    ``w_skate`` sees the teacher-forced one), where the data's feet are
    planted (``free_skate_contacts`` "data") or where that decode's own are ("own": a free decode's
    stride drifts out of step with the data's). ``w_foot_height`` weights the squared error of that
    decode's sorted foot heights (how long each foot spends at each height, phase-free), ``w_stance`` the
    squared error of the mean speed of its lowest foot against the data's (the foot it puts down stands;
    sorted heights say nothing of which foot is down while the other swings), ``w_heading``
    the squared error of the cosine between its hips' axis and its direction of travel (a body that
    does not face its path), ``w_twist`` the squared error of its torso twist per frame (the shoulders'
    axis turned against the hips'), ``w_coordination`` the relative squared error of the mean outer
    product of its joints' velocities (how each joint moves with every other: feet that alternate), of
    every joint or with ``coordination_on`` "legs" only the chains from the root to the foot joints.
    ``w_foot_twist`` weights the twist term's error for each foot (ankle to the joint below it) turned
    against the hips' axis (a foot a free run turns heel-first stays so: nothing else ties the toe's
    side of the ankle to the body). ``w_skim`` weights how far that decode's planted-foot speed by the
    skate metric's own rule, made soft (``skim_speeds``), exceeds the data's: the feet it keeps near the
    floor while they swing (the free-skate term's contacts are thresholded, so it cannot lift them).
    ``w_stand`` weights the squared error of that decode's mean root height over its lowest foot joint
    against the data's (legs drawn up under the body, which every term on heights over the window's own
    floor lets pass and the clean-up lowers onto the floor crouched), ``w_floor`` the squared error of
    that decode's sorted per-frame lowest-foot heights over the data's floor (feet lifted together, which
    the clean-up cannot lower without lowering the whole clip).
    ``spectrum_legs`` False leaves the legs out of the spectrum term. ``root_velocity_input`` feeds the
    pose decoder each frame's root velocity from the generated trajectory (the paper's decoder sees the
    trajectory only through its initial state, so it cannot tell how far the root moves at each frame
    to hold a planted foot against it). ``mean_pose_init`` starts the pose decoder's output at the
    training windows' mean root-centred pose (its bias; its weights scaled down), so that every seed
    starts from a body with its hips and shoulders on their own sides (from torch's default
    initialisation the decoder starts near the root and the sides each girdle takes are the seed's:
    the bundled recipe's seeds 1 and 2 cross both; with ``pose_output`` "rotations" it starts at the
    mean local rotations). ``pose_output`` "rotations" has the pose decoder emit each joint's local
    rotation (6D) and places the joints by forward kinematics on the skeleton (bone lengths and the
    girdles' shapes hold by construction; ``bone_projection`` is then unused); it reads back the joints
    as the "joints" decoder does, and needs ``root_relative_poses``. ``pose_update`` "residual" has a
    joint decoder emit each frame as a step from the previous pose, from a learned start pose (the
    paper's emits every pose afresh, and a decoder that does not read a joint's previous position, as the
    waves' hands measured in the README, holds it still at its mean). ``step_input`` has that decoder
    also read its previous step (each frame's previous pose minus the one before): a decoder that reads
    only where a joint is must infer from its own state which way it moves, and one-step predictions it
    cannot make shrink to the mean, which damps a swing it runs free. ``encoder_reverse`` has the LMP
    encoder read each window backwards, ending at its first frame: the paper's forward LSTM ends at the
    last frame, and its codes say little of where the window starts, which the decoder must produce first.
    ``clock_hz`` feeds the pose decoder sin and cos of each frame's time at these frequencies (Hz): its
    only other inputs are the code, constant over the window, and a ramp, so every rhythm it keeps up
    free-running is one its own state sustains, and measured ones die out (the waves, README).
    ``code_rhythms`` M adds M inputs, each a sum of those sines and cosines weighted by a linear function
    of the code: rhythms whose phase and size the code sets (the clock alone is the same in every window).
    ``scheduled_sampling`` says where the non-teacher-forced previous poses come from: "one_step" (a
    teacher-forced pass, the default) or "free_run" (a free-running decode, as the reference's per-step
    loop does; measured worse on the bundled recipe, see the README).
    """

    n_actions: int
    n_joints: int
    window: int = 60
    fps: float = 20.0
    latent_dim: int = 20
    enc_hidden: int = 64
    enc_fc: int = 256
    traj_hidden: int = 128
    motion_hidden: int = 128
    use_end_location: bool = True
    exact_end: bool = True
    root_relative_poses: bool = True
    alpha: float = 5.0
    prior_sigma2: float = 0.05
    w_recon: float = 1.0
    w_traj: float = 1.0
    w_consistency: float = 1.0
    w_contrastive: float = 1.0
    contrastive_pull: float = 1.0
    w_prior: float = 1.0
    traj_y_weight: float = 1.0
    lr: float = 1e-3
    batch_size: int = 128
    epoch_size: int = 2048
    epochs: int = 300
    tf_start: float = 1.0
    tf_end: float = 0.3
    tf_decay_epochs: int = 200
    grad_clip: float = 1.0
    train_precision: str = "float32"
    bone_projection: bool = True
    w_raw: float = 1.0
    foot_contact: bool = True
    w_contact: float = 1.0
    w_velocity: float = 0.1
    foot_joints: tuple[int, ...] = ()
    foot_heights: tuple[float, ...] = ()
    scheduled_sampling: str = "one_step"
    w_skate: float = 1.0
    w_free: float = 0.0
    free_span: int = 1
    free_shift: int = 0
    w_start: float = 0.0
    start_frames: int = 3
    w_rollout: float = 0.0
    rollout_frames: int = 15
    w_speed: float = 0.0
    w_upper_speed: float = 0.0
    upper_speed_span: int = 20
    speed_error: str = "absolute"
    speed_span: int = 0
    w_spectrum: float = 0.0
    spectrum_span: int = 0
    w_free_skate: float = 0.0
    spectrum_legs: bool = True
    free_skate_contacts: str = "data"
    w_foot_height: float = 0.0
    w_skim: float = 0.0
    w_stand: float = 0.0
    w_floor: float = 0.0
    w_stance: float = 0.0
    w_heading: float = 0.0
    w_twist: float = 0.0
    w_foot_twist: float = 0.0
    w_coordination: float = 0.0
    coordination_on: str = "all"
    root_velocity_input: bool = False
    mean_pose_init: bool = False
    pose_output: str = "joints"
    pose_update: str = "absolute"
    step_input: bool = False
    encoder_reverse: bool = False
    clock_hz: tuple[float, ...] = ()
    code_rhythms: int = 0
    arch: str = "odmo"

    POSITIVE = ("n_actions", "n_joints", "window", "fps", "latent_dim", "enc_hidden", "enc_fc", "traj_hidden")
    POSITIVE += ("motion_hidden", "prior_sigma2", "lr", "batch_size", "epoch_size", "free_span")
    POSITIVE += ("start_frames", "rollout_frames", "upper_speed_span")
    NON_NEGATIVE = ("w_recon", "w_traj", "w_consistency", "w_contrastive", "w_prior", "traj_y_weight")
    NON_NEGATIVE += ("w_raw", "w_contact", "w_velocity", "contrastive_pull", "epochs", "tf_decay_epochs")
    NON_NEGATIVE += ("w_skate", "w_free", "w_speed", "w_spectrum", "w_free_skate", "w_foot_height")
    NON_NEGATIVE += ("w_heading", "w_twist", "w_coordination", "speed_span", "spectrum_span", "free_shift")
    NON_NEGATIVE += ("w_start", "w_stance", "w_rollout", "w_upper_speed", "w_foot_twist", "w_skim")
    NON_NEGATIVE += ("w_stand", "w_floor", "code_rhythms")
    RATES = ("tf_start", "tf_end")
    CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {
        "train_precision": TRAIN_PRECISIONS,
        "speed_error": SPEED_ERRORS,
        "free_skate_contacts": FREE_SKATE_CONTACTS,
        "coordination_on": COORDINATION_ON,
        "pose_output": POSE_OUTPUTS,
        "pose_update": POSE_UPDATES,
        "scheduled_sampling": SCHEDULED_SAMPLING,
    }
    ARCH = "odmo"
    BEFORE = _BEFORE_SWITCHES

    def check(self) -> None:
        """Contrastive pairs and foot joints."""
        if self.pose_output == "rotations" and not self.root_relative_poses:
            raise ConfigError("pose_output 'rotations' needs root_relative_poses (the root is its path)")
        if self.pose_update == "residual" and self.pose_output != "joints":
            raise ConfigError("pose_update 'residual' steps joint positions: it needs pose_output 'joints'")
        if self.step_input and self.pose_update != "residual":
            raise ConfigError(
                "step_input feeds back the decoder's own steps: it needs pose_update 'residual'"
            )
        if self.w_rollout > 0 and self.rollout_frames >= self.window:
            raise ConfigError(
                f"rollout_frames must be below the window ({self.window}), got {self.rollout_frames}"
            )
        if self.batch_size < 2:
            raise ConfigError("batch_size must be at least 2 (windows come in contrastive pairs)")
        try:
            self.foot_joints = tuple(int(j) for j in self.foot_joints)
            self.foot_heights = tuple(float(h) for h in self.foot_heights)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"foot_joints and foot_heights must be lists of numbers ({exc})") from None
        try:
            self.clock_hz = tuple(float(f) for f in self.clock_hz)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"clock_hz must be a list of frequencies in Hz ({exc})") from None
        if self.code_rhythms and not self.clock_hz:
            raise ConfigError("code_rhythms are sums of the clock's sines: give clock_hz too")
        if len(self.clock_hz) > MAX_CLOCK_FREQUENCIES:
            raise ConfigError(f"clock_hz holds at most {MAX_CLOCK_FREQUENCIES} frequencies")
        if any(not 0 < f <= self.fps / 2 for f in self.clock_hz):
            raise ConfigError(f"clock_hz must lie in (0, fps / 2 = {self.fps / 2:g}] Hz, got {self.clock_hz}")
        if self.foot_heights and len(self.foot_heights) != len(self.foot_joints):
            raise ConfigError("foot_heights needs one height per foot joint")
        if any(not 0 <= j < self.n_joints for j in self.foot_joints):
            raise ConfigError(f"foot_joints must be joint indices below {self.n_joints}")

    def teacher_forcing(self, epoch: int) -> float:
        """Teacher-forcing rate of ``epoch`` (0-based): linear from tf_start to tf_end, then constant."""
        if self.tf_decay_epochs == 0:
            return self.tf_end
        frac = min(epoch / self.tf_decay_epochs, 1.0)
        return self.tf_start + (self.tf_end - self.tf_start) * frac
