"""Physical plausibility of generated followers, each beside the same number for the real followers.

- bone_error_cm: mean over frames and bones of |bone length - the real follower's median length of that
  bone in the sequence| (a rigid skeleton keeps its bones; Kinect's real followers score a few cm too).
- interpenetration: share of frames in which some limb or trunk segment of A and of B have axes closer
  than PENETRATION_M (contact.py). Limbs are at least ~8-10 cm thick, so two axes within 5 cm means the volumes
  overlap by half a limb or more, but real followers come that close in a quarter of handshake and half of hug
  frames: in those classes it counts contact too.
- foot_skate_mps: mean horizontal speed of feet in ground contact (within CONTACT_M of the sequence's
  lowest foot height at both ends of a frame step, as in GMD's skating measure, Karunratanakul et al. 2023: the step
  on which a foot lifts off is the foot leaving the floor, not sliding on it).
- speed_ratio: mean joint speed of the generated followers over that of the real ones, and limb_speed_ratio
  the same for joints relative to the follower's own root. Real motion is first smoothed with a
  Savitzky-Golay filter (window 7, order 2) so that Kinect jitter does not count as motion; smooth_limb_speed_ratio
  smooths the generated motion too, so a model cannot reach the real speed by jittering.
- body_limb_speed_ratio: the same for joints relative to the centre of the root's neighbours (Kinect: neck and hips),
  and root_sway_mps the root's own speed relative to that centre. A root joint that sways inside the body moves
  every joint relative to it, so limb_speed_ratio counts that sway as limb motion and this ratio does not
  (docs/experiments/motion-energy.md). interior_limb_speed_ratio: the same over the frames at least
  EDGE_FRAMES from either end, because a sequence-to-sequence network moves most in its first and last frames.
- lean_error_deg: mean over sequences of |the follower's torso lean - the real follower's| (degrees; the lean is the
  angle of hips-centre-to-neck from the vertical, + towards the follower's own facing, averaged over the sequence). A
  model that caricatures its class (a punched follower thrown far back) scores high here; AFD hides it among limbs.
- jitter_mps2: mean joint acceleration magnitude, |second difference of positions| x fps^2 in m/s^2 at the data's frame
  rate, over frames and joints, averaged over sequences; real_jitter_mps2 the same for the real followers, unsmoothed
  (Kinect's own jitter is part of what real motion looks like), and jitter_ratio generated / real: 1 = as jerky as the
  recorded followers, above 1 = a model adds high-frequency noise.
"""

from __future__ import annotations

import numpy as np

from imm_model.contact import CONTACT_M, PENETRATION_M, bone_pair_distances, closest_distances
from imm_model.data.canonical import facing_direction
from imm_model.skeleton import Skeleton

FRAME_RATE = {"sbu": 15.0}  # K3HI's rate is not documented (its PROVENANCE.md); SBU's is used for it
SMOOTH_WINDOW = 7
EDGE_FRAMES = 3  # interior_limb_speed_ratio leaves out this many frames at either end, where networks move most


def frame_rate(dataset: str) -> float:
    return FRAME_RATE.get(dataset, 15.0)


def smooth(motion: np.ndarray) -> np.ndarray:
    """Savitzky-Golay smoothing in time of (T, J, 3); sequences shorter than the window are left as they are."""
    if len(motion) < SMOOTH_WINDOW:
        return motion
    from scipy.signal import savgol_filter  # here: scipy.signal costs ~1 s to import, and the studio never smooths

    return savgol_filter(motion, SMOOTH_WINDOW, 2, axis=0)


def bone_error_cm(follower: np.ndarray, real: np.ndarray, skeleton: Skeleton) -> float:
    reference = np.median(skeleton.bone_lengths(real), axis=0)
    return float(np.abs(skeleton.bone_lengths(follower) - reference).mean() * 100.0)


def penetrating_bones(leader: np.ndarray, follower: np.ndarray, skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """-> closest distance (T,), and which bones of A (T, K) and of B (T, K) come within PENETRATION_M of the other."""
    d = bone_pair_distances(leader, follower, skeleton)
    close = d < PENETRATION_M
    return d.min(axis=(1, 2)), close.any(axis=2), close.any(axis=1)


def interpenetration(leader: np.ndarray, follower: np.ndarray, skeleton: Skeleton) -> float:
    return float((closest_distances(leader, follower, skeleton) < PENETRATION_M).mean())


def foot_skate_mps(follower: np.ndarray, skeleton: Skeleton, fps: float) -> float:
    feet = [skeleton.joint_names.index(n) for n in ("left_foot", "right_foot") if n in skeleton.joint_names]
    if not feet or len(follower) < 2:
        return float("nan")
    up = skeleton.vertical_axis
    pos = follower[:, feet]  # (T, 2, 3)
    on_floor = pos[..., up] < pos[..., up].min() + CONTACT_M
    contact = on_floor[:-1] & on_floor[1:]
    horizontal = np.delete(np.diff(pos, axis=0), up, axis=-1)
    speed = np.linalg.norm(horizontal, axis=-1) * fps
    return float(speed[contact].mean()) if contact.any() else 0.0


def mean_speed(motion: np.ndarray, fps: float, reference: int | list[int] | None = None,
               joints: int | list[int] | slice = slice(None), edge: int = 0) -> float:
    """Mean speed (m/s) of `joints` of (T, J, 3); relative to joint `reference` (or the centre of several) when given;
    with `edge`, over the frames at least that far from either end only (nan when there are none)."""
    if len(motion) < 2:
        return 0.0
    if reference is not None:
        motion = motion - motion[:, np.atleast_1d(reference)].mean(1, keepdims=True)
    speeds = np.linalg.norm(np.diff(motion[:, joints], axis=0), axis=-1)[edge:len(motion) - 1 - edge]
    return float(speeds.mean() * fps) if len(speeds) else float("nan")


def acceleration_mps2(motion: np.ndarray, fps: float) -> float:
    """Mean |x[t+1] - 2 x[t] + x[t-1]| x fps^2 (m/s^2) over frames and joints of (T, J, 3); nan under 3 frames."""
    if len(motion) < 3:
        return float("nan")
    return float(np.linalg.norm(np.diff(np.asarray(motion, np.float64), n=2, axis=0), axis=-1).mean() * fps * fps)


def torso_lean_per_frame_deg(motion: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(T, J, 3) -> (T,) the torso's angle from the vertical (degrees, + = towards its own facing): the vector from the
    hips' centre (the root's neighbours other than the top one) to the highest neighbour (the neck); NaN without one."""
    up = skeleton.vertical_axis
    neighbours = skeleton.root_neighbours
    if len(neighbours) < 2:
        return np.full(len(motion), np.nan)
    top = max(neighbours, key=lambda j: motion[:, j, up].mean())
    torso = motion[:, top] - motion[:, [j for j in neighbours if j != top]].mean(1)
    forward = (torso * facing_direction(motion, skeleton)).sum(-1)
    return np.degrees(np.arctan2(forward, torso[:, up]))


def torso_lean_deg(motion: np.ndarray, skeleton: Skeleton) -> float:
    """(T, J, 3) -> the mean over frames of torso_lean_per_frame_deg."""
    return float(torso_lean_per_frame_deg(motion, skeleton).mean())


def plausibility(leaders: list[np.ndarray], followers: list[np.ndarray], reals: list[np.ndarray],
                 skeleton: Skeleton, fps: float) -> dict[str, float]:
    """Means over sequences for generated followers, with the real followers' values as `real_*`."""
    root = skeleton.root

    def stats(bs: list[np.ndarray]) -> dict[str, float]:
        return {
            "bone_error_cm": float(np.mean([bone_error_cm(b, r, skeleton) for b, r in zip(bs, reals, strict=True)])),
            "interpenetration": float(np.mean([interpenetration(a, b, skeleton) for a, b in zip(leaders, bs, strict=True)])),
            "foot_skate_mps": float(np.nanmean([foot_skate_mps(b, skeleton, fps) for b in bs])),
        }

    real_smooth = [smooth(np.asarray(r, np.float64)) for r in reals]
    speed = lambda ms, *where, **kw: float(np.nanmean([mean_speed(m, fps, *where, **kw) for m in ms]))  # noqa: E731
    gen, real = stats(followers), stats(reals)
    out = gen | {f"real_{k}": v for k, v in real.items()}
    out["speed_mps"], out["real_speed_mps"] = speed(followers), speed(real_smooth)
    out["limb_speed_mps"], out["real_limb_speed_mps"] = speed(followers, root), speed(real_smooth, root)
    out["speed_ratio"] = out["speed_mps"] / out["real_speed_mps"]
    out["limb_speed_ratio"] = out["limb_speed_mps"] / out["real_limb_speed_mps"]
    # the same with the generated motion smoothed too: motion that is only jitter scores far lower here
    out["smooth_limb_speed_ratio"] = speed([smooth(np.asarray(b, np.float64)) for b in followers], root) / out["real_limb_speed_mps"]
    body = skeleton.root_neighbours
    out["body_limb_speed_ratio"] = speed(followers, body) / speed(real_smooth, body)
    out["root_sway_mps"], out["real_root_sway_mps"] = speed(followers, body, root), speed(real_smooth, body, root)
    interior = {"edge": EDGE_FRAMES}
    out["interior_limb_speed_ratio"] = speed(followers, body, **interior) / speed(real_smooth, body, **interior)
    out["jitter_mps2"] = float(np.nanmean([acceleration_mps2(b, fps) for b in followers]))
    out["real_jitter_mps2"] = float(np.nanmean([acceleration_mps2(r, fps) for r in reals]))
    out["jitter_ratio"] = out["jitter_mps2"] / out["real_jitter_mps2"] if out["real_jitter_mps2"] > 0 else float("nan")
    out["lean_error_deg"] = float(np.nanmean([abs(torso_lean_deg(b, skeleton) - torso_lean_deg(r, skeleton))
                                           for b, r in zip(followers, reals, strict=True)]))
    return out
