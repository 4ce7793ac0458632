"""Front/back hypotheses carried over time: which of the regressor's poses is the true one.

A silhouette cannot tell a body from its reflection in depth (sequences.pose_vector.
front_back_flip: heading h -> 180 - h, left and right exchanged). So each frame the regressor
proposes K hypotheses (:func:`propose`): its pose and that pose's flip, or, for a mixture of
experts with ``predict_hypotheses(stacked, m)``, each expert's pose and its flip. The tracker
keeps a discrete state per track, s_t in {0..K-1}: which hypothesis of frame t is the truth, in
a hidden Markov model (one Kalman filter per state, as in a GPB / IMM filter bank):

    alpha_t(j) = e_t(j) * sum_i alpha_{t-1}(i) A_ij N(z_t(j); filter i's prediction)

- A: the switching probabilities. The body's heading does not change by ~180 degrees within a
  frame, so the state switches only where the regressor's flips do: P(raw -> flip) and
  P(flip -> raw) from one frame to the next on the validation trials rendered as spiral walks
  (SWITCH_PROBABILITY, learned by scripts/learn_hypothesis_priors.py).
- N(...): the innovation likelihood of hypothesis j under the filter of the predecessor i
  (PoseKalmanFilter.log_likelihoods, 54 angles). Filter j continues the best predecessor's
  filter, updated with hypothesis j. A pose consistent with the track's past explains it well;
  a regressor flip is explained by switching state, not by a jump of the body.
- e_t(j): the evidence for j that the frame itself gives. The regressor's: the (cos, sin) norm
  n says how often its raw pose, not the flip, is the nearer one (RAW_NEARER_BY_NORM, validation
  renders), turned into a likelihood ratio P(raw | n) / P(raw). The direction of travel's, while
  the person moves: the likelihood of the travel seen given hypothesis j's heading and the
  track's belief over (facing - travel) (below): backwards and sideways walking are less
  likely than forwards at first, never excluded.
- The belief over (facing - travel) (``offset_memory``, on by default): each state's filter
  carries a probability over tracker.travel.FACING_TRAVEL_PRIOR's twelve 30-degree bins,
  starting at that population prior and moved from frame to frame by the bins' transitions
  learned from the CMU training trials (tracker.travel.offset_transition: a moving body's
  offset drifts a bin at a time and persists). Each frame with travel updates it by the
  travel's likelihood under the state's heading (tempered by TRAVEL_WEIGHT, as the evidence),
  and the travel evidence for state j after state i is p(travel | j's heading) under i's
  predicted belief, so it sits in the link, not in e_t. The travel fused into j's heading
  (tracker.travel.fuse_with_prior) takes the same belief as its prior. Why: people who walk
  backwards or sideways keep doing so, and one frame's travel is not independent of the
  last's. With the population prior on every frame (``offset_memory=False``, the chain before
  2026-12-04) a sideways dribble was read as turned towards its travel on every frame.
  The belief waits on frames without travel (its steps were counted on moving frames; stepping
  there let a still track's belief drift to the steps' own long-run distribution, twice the
  population's backwards share). Measured (2026-12-04, the shipped model; filtered heading RMS,
  degrees). Chosen on validation: the 28 validation renders (the chain replayed as ``track``
  builds it) 30.34 -> 29.44 (as recorded 24.13 -> 24.41, time-reversed, i.e. walking backwards,
  36.54 -> 34.47), corr8 0.581 -> 0.585 (stepping on every frame: 29.23, not taken for the
  drift); the 12 validation videos through ``track`` 31.47 -> 31.41, corr8 0.446 -> 0.447,
  smoothed 23.22 -> 23.18. The belief's update is tempered by TRAVEL_WEIGHT (0.04), as the
  travel evidence is; an exponent of its own instead, 0.02 / 0.1 / 0.2 / 0.5 / 1, gave 29.47 /
  29.22 / 28.93 / 29.30 / 29.44 on the renders (stepping on every frame): no clear gain for
  another parameter. Offline (``--smooth``) the Viterbi path takes each frame's hypotheses as
  fused under the forward pass's best predecessor's belief, which may not be the path's own
  predecessor: an approximation. Held out, after the choice (evaluate_jitter.py --through-video,
  fixed camera and --spiral 30; the sample by evaluate_accuracy.py; filtered / smoothed): the
  sideways dribble 06_08 from a fixed camera 28.1 / 24.5 -> 21.5 / 19.3, as a spiral 11.3 / 11.8
  -> 8.4 / 6.5; the backward dribble 06_06 fixed 7.2 / 7.5 -> 7.0 / 7.2, spiral 10.0 / 5.7 ->
  11.3 / 8.0; the sample 7.9 / 6.0 -> 7.8 / 5.8.
  Consecutive frames' evidence is correlated (stacked descriptors share frames; travel windows
  overlap), so each is tempered by an exponent per frame, EVIDENCE_WEIGHT for the regressor's
  (CANONICAL_EVIDENCE_WEIGHT for canonical pairs) and TRAVEL_WEIGHT for travel's, chosen on
  validation renders (see those constants).

Tried and reverted (2026-12-01, commit 4862a54): splitting the flip into its heading part (h ->
180 - h) and its limb part (left/right mirrored) as two independent chains, four states per
pose, because the regressor's heading and limb errors are nearly independent (on validation
spirals its heading is nearer than the reflected one in 58 % of frames, its limbs nearer than
the mirrored ones in 72 %, the two agreeing in 59 %). On the 28 validation renders it lowered
the 53 body angles' error 9.197 -> 9.059 deg and raised corr8 0.185 -> 0.242 at equal heading
RMS (79.1 vs 79.5), but on held-out sequences it lost: heading RMS 06_06 fixed 51 -> 152,
06_08 spiral 43 -> 73, Pose2Sim cross-view 97 -> 120, and 06_06's corr8 0.18 -> 0.12. Coupled,
the limbs' innovations (72 % right) carry the heading with them; split, the heading's own
evidence is too weak and the travel prior turns backward walkers round.

Tried and not adopted (2026-12-02, a one-off patch): hypotheses carrying the limb head's member
that agrees with each hypothesis's heading as their body angles (so the flip also swaps the
limbs and the limbs' continuity helps decide the side in profile, where picking the member by
the decided heading errs: with the member picked by the true heading, corr8 would rise 0.546 ->
0.616 on the sample, 0.600 -> 0.685 on 02_02, 0.682 -> 0.726 on 08_03). On the five validation
videos it helped (filtered heading 28.0 -> 27.7, corr8 0.392 -> 0.407, 08_03 0.682 -> 0.717),
but on the 28 validation renders it lost (filtered heading 59.5 -> 62.4, corr8 0.361 -> 0.339):
backward walks, which it turned round (02_02 spiral reversed 25 -> 76 degrees, 09_04 22 -> 83,
07_12 29 -> 109). Flip tables re-learned for it (raw nearer 0.62, switches 0.17 / 0.27) were
worse still online (validation videos filtered heading 38.6-47.7). Also tried then: the chain's
heading variance scaled by 0.35 (its R is mostly front/back confusions, which the states already
model; a smaller one should make a 75-degree innovation cost more than a switch, as at 16_11's
frames 212-227, where the chosen filter ramps to the flip's heading): worse on both sets
(videos 28.0 -> 31.2 degrees, corr8 0.392 -> 0.359; renders 59.5 -> 60.4, 0.361 -> 0.341).
Later the same day, with the limb networks (a one-off patch): a front/back classifier, a ReLU
network (200 -> 512 -> 256 -> 1) on the regressor's input fitted on the training rows to say
whether the heading faces the camera's half (91.6 % right on its held-out tenth), its log-odds
(probability clipped to 0.05-0.95) in place of the heading-norm table as each hypothesis's
side evidence. Per frame it is right more often than the raw heading's side on the validation
videos (02_02 / 08_03 / 05_02 / 09_04 / 02_05: 0.80 / 0.86 / 0.65 / 0.75 / 0.57 against 0.71 /
0.74 / 0.57 / 0.57 / 0.53), but it is confident where it is wrong (05_02: |p - 0.5| > 0.4 on 95 %
of frames, right on 67 %): through ``track`` the filtered / smoothed heading went 28.0 / 25.1 ->
31.9 / 32.4 (weight 1; 0.5: 34.3 / 31.8; added to the heading-norm evidence with weight 0.3
instead of replacing it: 33.7 / 32.0), 05_02 28.9 -> 58.9, though 02_02 15.6 -> 13.2 and
corr8 0.430 -> 0.438. It needs calibration on video-like inputs before it can be evidence.
Also tried then: near profile (folded decided heading beyond 60 or 30 degrees) taking the limb
member nearer the limb filter's predicted body angles instead of the decided heading's side:
it locks onto mirrored legs (08_03 filtered corr8 0.693 -> 0.487 / 0.449; 02_02 0.656 -> 0.650
/ 0.508).

Tried and not adopted (2026-12-02, ``fuse_travel=False``): no fusion of the direction of
travel into the hypotheses' headings (the travel likelihood still weighs the states). The
fusion moment-matches the mocap's mostly-forward (facing - travel) prior into one direction,
and with the chain's heading standard deviation (37 degrees) it pulls a sideways walker's heading
towards its travel: on 06_08 from a fixed camera (held out) the filtered heading sits 20
degrees beyond the raw one for the second half. Without it, on the 28 validation renders
filtered / smoothed heading RMS 36.4 / 28.5 -> 32.9 / 24.4 degrees and corr8 0.561 / 0.630
-> 0.568 / 0.632 (the time-reversed renders gain, 41.9 -> 34.4; the forward ones lose, 30.8
-> 31.5), but on the five validation videos, all walking forwards or on the spot, corr8 0.481
-> 0.460 (02_02 0.698 -> 0.637, 08_03 0.784 -> 0.760) and heading 36.8 -> 37.2 (09_04 15.2 ->
18.4). The two sets disagree, so it stays; reported after the choice: 06_08 fixed 30.0 ->
23.4 filtered, 25.4 -> 19.7 smoothed. Also tried: the chain's heading variance x 0.1 in
the fusion (its offset posterior, its weights and the fused variance the filter gets): worse
on the renders (37.9 / 29.6, corr8 0.533 / 0.606); a within-state variance (100 deg^2) in the
offset posterior only, so that a heading far from the travel is not read as forwards:
neutral (renders 36.3 / 28.5, corr8 0.561 / 0.628; videos corr8 0.476, heading 36.7).

Canonical hypotheses (the default model since 2026-12-02: it has limb networks and a side
classifier, regressor.side_classifier): the two states are the limb networks' canonical member
and its flip, whole (heading and body angles; :func:`canonical_hypotheses`), not the main
head's pose and its flip. The main head averages a silhouette's two bodies where it cannot
tell them apart, so its heading is pulled towards profile (on the shipped sample it stays
near -90 while the truth goes from -125 to -50); the canonical member commits to one body.
With the side picked by the truth, its heading RMS on the masks ``track`` extracts is 7.1 /
8.2 / 12.7 / 10.4 / 25.3 degrees on the five validation videos (02_02 / 08_03 / 05_02 / 09_04
/ 02_05; held out: 16_11 6.9, 06_06 8.0, 06_08 9.3), against 15.8 / 17.0 / 14.9 / 19.9 / 27.0
for the main head's pose or its flip. Which member is true changes only where the member's
rule does (mostly in profile), so the chain's states switch rarely
(CANONICAL_SWITCH_PROBABILITY); the evidence for a member is the side classifier's
probability, calibrated on validation renders (CANONICAL_BY_FRONT), and the main head's
side (CANONICAL_RAW_SIDE_BY_NORM). These priors belong to a model's networks, so the model
file carries its own (regressor.canonical_priors: scripts/train.py learns them on the
validation renders); the CANONICAL_* constants are the shipped model's, taken for a file
without them (:func:`canonical_priors`). Chosen on the 28 validation renders (filtered heading RMS
and corr8, mean; one-off drivers) and the five validation videos through ``track``:

| chain | renders heading / corr8 | videos heading / corr8 |
| pose and flip (before) | 59.5 / 0.427 | 28.0 / 0.430 |
| canonical, main head's side only | 56.4 / 0.400 | - |
| canonical, classifier 512 x 256 (0.47 MB) | 38.6 / 0.524 | 30.7 / 0.412 |
| canonical, classifier 128 | 44.3 / 0.503 | 24.6 / 0.426 |
| canonical, classifier 256 x 64 (0.13 MB) | 32.8 / 0.557 | 33.3 / 0.427 |
| the same refitted by scripts/train.py | 36.1 / 0.545 | 33.0 / 0.415 |
| and the pair given the main head's norm (the default) | 36.1 / 0.541 | 32.1 / 0.440 |

(The one-off classifiers were fitted outside train.py; train.py's refit of the 256 x 64 one
differs in its last digits' arithmetic, so SGD took another path: held-out accuracy 0.901 vs
0.899; its table is the one above. The member's norm is ~1 even where the silhouette is
ambiguous, so the pair takes the main head's norm: the filters' ambiguity handling and the
ambiguous flag read it.) On the videos the walks gain most (02_02 15.6 -> 8.1 degrees, corr8
0.656 -> 0.704; 08_03 13.2 -> 8.0, 0.693 -> 0.718); the dance 05_02 loses (28.9 -> 56.3: the
classifier and the member hold the wrong side for long stretches), 09_04 filtered 10.1 ->
19.5 (smoothed 7.8 -> 6.2), and 02_05 stays lost (72.3 -> 68.4; with the one-off 128
classifier 45.3, with the 256 x 64 one 88.7: it locks to either side). Held out (through-video evaluate_jitter,
filtered / smoothed heading RMS): 16_11 spiral 24.7 / 14.5 -> 7.9 / 7.4, 06_06 fixed 9.3 / 9.2
-> 7.0 / 7.2, spiral 19.3 / 11.5 -> 9.4 / 4.8, 06_08 spiral 19.3 / 15.9 -> 14.6 / 13.5, but
06_08 fixed 33.2 / 26.8 -> 33.4 / 30.1 (a sideways dribble seen from one side). Tried and not
adopted (a one-off patch, 2026-12-02): the main head's side as P(member true | member on the
main head's side or not, norm bin) over the canonical base rate, instead of over its own base
rate (which the chain then never sees): filtered heading better, smoothed worse (renders
36.1 / 27.8 -> 34.3 / 33.5 degrees, smoothed corr8 0.609 -> 0.573; videos 32.1 / 31.1 ->
30.4 / 31.7, corr8 0.440 both).

Online the chosen pose is the most probable state's filtered pose; the runner-up and its
probability are reported when close (CLOSE_PROBABILITY). Offline (``--smooth``) the Viterbi path
picks one hypothesis per frame and the Rauch-Tung-Striebel smoother runs over them.

Limbs (``limb_filter_factory``, the tracker's default): the chain above decides the heading,
but the output's 53 body angles come from one more filter over the regressor's own pose (no
flips), whose measurement noise is the white part of the regressor's error only
(tracker.pipeline.LIMB_R_SCALE). Why: the chain's flips are mostly heading decisions (the raw
heading beats its reflection in only 57 % of validation frames, the raw limbs beat the
mirrored ones in 72 %, nearly independently), so following them swapped good limbs for
mirrored ones; and the chain's filters take the regressor's whole residual variance as white
noise, while ~92 % of it is slow bias the filter cannot remove, so they smoothed the gait away
(lag). Measured on track's own inputs (five spiral-walk videos, the shape-context mixture of
2026-12-01 before the layout block, correlation of the 8 most-moving angles, raw / chain / this): 16_11 0.25 / 0.20 / 0.25, 02_02 0.37 / 0.21 / 0.38,
08_03 0.39 / 0.11 / 0.41, 06_06 0.20 / 0.14 / 0.19, 06_08 0.24 / 0.24 / 0.27.

With limbs from the model (its limb networks, regressor.limb_net, or its limb head,
regressor.pose_model.LimbHead: PoseModel.predict_limbs, Hypotheses.limbs; "the limb head"
below) that filter's input is not the
regressor's own pose but the limb head's canonical member or its flip, whichever has the
heading nearer the heading the chain decided (pick_member). The own pose averages a
silhouette's two bodies where it cannot tell them apart (in profile, which leg is forward); the
limb head gives one of them, and the decided heading says which. Offline (``--smooth``) the
members are those of the most probable chain given the smoothed heading and the limbs'
continuity (tracker.member_path: in profile the heading cannot say which leg is forward).
The limb filter measures the decided heading with them (its R, the main head's residual
covariance, couples heading and joints). Its noise model is still the main head's
(LIMB_R_SCALE re-checked with the limb head on the validation videos: 0.03 / 0.1 / 0.3 / 1.0
give mean corr8 0.392 / 0.395 / 0.395 / 0.382).
"""
from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from regressor.angles import heading_norm
from regressor.canonical_priors import CanonicalPriors
from regressor.pose_model import DEFAULT_TRAINING_FPS, training_fps_of
from regressor.stacking import stack_frames
from sequences.pose_vector import front_back_flip, heading_deg
from .member_path import members_over_time
from .mirror_limbs import mirror_mean, sees_mirror
from .travel import (FACING_TRAVEL_FPS, FACING_TRAVEL_PRIOR, fuse_with_priors,
                     offset_likelihoods, offset_transition)

#: P(the raw pose is nearer the truth than its flip | raw heading norm in
#: [RAW_NEARER_NORM_EDGES[b], RAW_NEARER_NORM_EDGES[b + 1])); and over all frames. Measured on
#: the default model's validation trials (02_02, 08_03, 05_02, 06_10, 09_04, 02_05) rendered as
#: 30 deg/s spiral walks, 300 frames each, the masks made video-like as in training
#: (tracker.offline.hypothesis_priors.video_like), by scripts/learn_hypothesis_priors.py.
#: "Nearer": smaller mean absolute error over the 54 angles. For the mixture of 24 experts
#: (default since issue 9) each of the top DEFAULT_EXPERTS experts' poses counts as a raw pose
#: and switches are counted per expert slot, pooled; with DEFAULT_EXPERTS = 1 that is the top
#: expert's pose (1800 frames). Re-learned 2026-12-01 for the model with the silhouette layout
#: (regressor.layout) with `python scripts/learn_hypothesis_priors.py`; on the crisp renders
#: (before video_like) the same model gave (0.569, 0.674, 0.685, 0.666, 0.676, 0.760), 0.691,
#: switch (0.073, 0.164), the shape-context-only mixture before it (0.700, 0.591, 0.689, 0.700,
#: 0.769, 0.668), 0.682, (0.079, 0.170); the single RVM (0.622, 0.661, 0.631, 0.720, 0.612,
#: 0.508), 0.647, (0.115, 0.207). Bins hold 116-376 frames, so differences of a few points
#: between them are noise. The norm carries little of it: in profile the flip only swaps the limbs, which the
#: regressor often confuses.
RAW_NEARER_NORM_EDGES = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)
RAW_NEARER_BY_NORM = (0.672, 0.617, 0.646, 0.703, 0.744, 0.688)
RAW_NEARER_OVERALL = 0.681
#: (P(raw -> flip), P(flip -> raw)): how often the nearer of the two changes from one frame to
#: the next (30 fps), same data: the regressor's flips, not the body's.
SWITCH_PROBABILITY = (0.117, 0.248)
#: Exponents per frame of the travel likelihood and of the regressor's evidence (log
#: likelihoods are multiplied by them). Chosen by the mean filtered heading RMS over the
#: validation trials and 07_12 rendered as spiral walks and from a fixed camera, as recorded
#: and time-reversed (backward walks; tracker.offline.hypothesis_priors.validation_renders,
#: replay_heading_rms), keeping only pairs under which the hand-made backward walker of
#: tests/test_hypotheses.py still ends up facing the right way. Re-chosen 2026-12-01 for the
#: mixture (DEFAULT_EXPERTS = 1, the tables above): of choose_weights' grid only travel weight
#: 1/15 with evidence weight >= 0.8 kept the backward walker under the top-3 tables and none
#: under the top-1 tables, so a finer travel weight was tried with the same replay (a one-off
#: driver, not the script's --weights): (1/15, 1.0) 79.6 deg, (1/15, 0.8) 80.6 (both lose the
#: backward walker); (0.05, 1.2) 79.4, (0.04, 1.0) 79.5: the latter, inside the backward
#: walker's region (travel weight <= 0.04 keeps it for evidence weights 0.8-1.2). Old values (single RVM): 0.1, 0.8 (83.8 deg there).
#: Kept for the model with the silhouette layout (2026-12-01, a one-off driver over the same 28
#: renders made video-like, limbs as the tracker filters them): with these tables (0.04, 1.0)
#: 72.0 deg (forward renders 50.1, time-reversed 93.8), (0.02, 1.0) 71.8, (0.1, 1.0) 72.7,
#: (0.04, 0.6) 72.6, (1/15, 0.8) 72.5; with the tables learned on crisp renders 72.8 at (0.04,
#: 1.0), with a flat table (norm ignored) 75.3. The backward walker of tests/test_hypotheses.py
#: ends facing the right way under these tables.
TRAVEL_WEIGHT = 0.04
EVIDENCE_WEIGHT = 1.0
CLOSE_PROBABILITY = 0.2                  # the runner-up is reported from this probability on

#: Canonical hypotheses (a model with limbs and a side classifier; module docstring,
#: "Canonical hypotheses"). All learned on the 28 validation renders of
#: scripts/learn_hypothesis_priors.py (validation trials and 07_12, spiral and fixed camera, as
#: recorded and time-reversed, video-like masks), 2026-12-02, by
#: tracker.offline.hypothesis_priors.canonical_statistics, for the shipped model's networks.
#: A model file carries its own (PoseModel.canonical_priors, regressor.canonical_priors:
#: scripts/train.py learns them, `scripts/learn_hypothesis_priors.py --save` adds them to a
#: file); these are DEFAULT_CANONICAL_PRIORS, taken only for a model file without them.
#: "True": the member with the smaller mean absolute error over the 54 angles.
#: (P(canonical -> flip), P(flip -> canonical)) per frame: how often the truer member changes.
#: The limb network's canonical member changes body only where its rule does (mostly in
#: profile), so these are far below SWITCH_PROBABILITY's.
CANONICAL_SWITCH_PROBABILITY = (0.025, 0.041)
#: EVIDENCE_WEIGHT for the canonical chain. Chosen 2026-12-03 on the 28 validation renders (the
#: chain replayed as ``track`` builds it, one-off driver /work/tmp/s32/replay.py; mean filtered
#: heading RMS / corr8 of the 8 most-moving angles): weight 1 35.2 deg / 0.572, 1.5 34.7 /
#: 0.569, 2 32.1 / 0.582, 3 32.1 / 0.586, 4 32.2 / 0.586, 6 35.4 / 0.574 (travel weight 0.02 /
#: 0.08 with weight 2: 31.6 / 32.6, so TRAVEL_WEIGHT stays). Why the canonical chain wants more
#: than 1: filter j continues its best predecessor's, so while the chain holds the member, the
#: flip's filter is a fresh copy of the member's, updated with the flip once, every frame; its
#: own continuation then scores 3-7 nats a frame below the member's, and evidence of about 1 nat
#: a frame never catches up (05_02's spiral, validation: the member held for 180 frames through
#: a turn from profile to the back while the side evidence favoured the flip on ~100 of them).
#: On the five validation videos through ``track`` (02_02 / 08_03 / 05_02 / 09_04 / 02_05),
#: weight 1 -> 2: filtered heading RMS 8.7 / 8.5 / 74.1 / 7.2 / 79.2 -> 9.0 / 8.6 / 26.9 / 8.1 /
#: 65.5 deg, err53 mean 7.74 -> 7.59, corr8 0.708 / 0.786 / 0.071 / 0.477 / 0.364 -> 0.692 /
#: 0.771 / 0.058 / 0.477 / 0.359. Tried and not adopted the same day: each state keeping its own
#: filter (continued from itself whatever the best predecessor; or from the predecessor whose
#: filter explains the pose best, which came to the same), so the evidence alone moves the
#: chain: on the 28 renders heading 35.2 -> 37.8 deg (median 17.5 -> 23.8), corr8 0.572 ->
#: 0.573; with evidence weight 0.3-2 and switch rates x0.3-1 no better (37.7-46.0).
CANONICAL_EVIDENCE_WEIGHT = 2.0
#: P(the member on the main head's heading side is the true one | that head's heading norm
#: in [CANONICAL_RAW_SIDE_EDGES[b], next edge)), and overall: weak, but not nothing.
CANONICAL_RAW_SIDE_EDGES = (0.0, 0.2, 0.4, 0.6, 0.8)
CANONICAL_RAW_SIDE_BY_NORM = (0.504, 0.507, 0.538, 0.613, 0.669)
CANONICAL_RAW_SIDE_OVERALL = 0.578
#: P(the canonical member is the true one | the side classifier's probability for that
#: member in [CANONICAL_FRONT_EDGES[b], next edge)), and overall. The classifier is
#: over-confident on renders that are not like its training rows: where it gives the member
#: less than 0.1, the member is still the true one 4 times in 10, and the middle bins barely
#: differ (0.61-0.65: noise at 227-419 frames each) (for the default model's
#: classifier, 256 x 64 hidden units; right on 67 % of these frames, 90 % of its held-out
#: training rows).
#: Tried and not adopted (2026-12-02): the table by the member's |cos heading| too (rows 0 /
#: 0.2 / 0.4 / 0.6, cells shrunk towards their row's rate by 20 frames). Near profile the
#: classifier is right only half the time where it is sure (>= 0.9: 0.51 at |cos| < 0.2,
#: 0.84 at >= 0.6), and with one row the chain holds the member for ~10 frames after the
#: truth turns through profile, its limbs then the mirrored ones (02_02, 08_03). The 2-D table
#: gained on validation (28 renders, in-sample for the table: filtered heading 32.7 -> 28.1,
#: corr8 0.546 -> 0.558; five videos corr8 0.704 / 0.718 / 0.052 / 0.453 / 0.264 -> 0.730 /
#: 0.786 / 0.067 / 0.453 / 0.252, heading 05_02 47.3 -> 56.9) but lost on the held-out
#: sequences (evaluate_accuracy, filtered corr8 / heading: 16_11 0.704 / 6.8 -> 0.601 / 12.5,
#: 06_06 0.496 / 9.4 -> 0.462 / 10.6, 06_08 0.497 / 14.6 -> 0.493 / 15.5). Why (looked at
#: after the choice): near profile the classifier leans to "front" (within 17 deg of profile it
#: says front on 49 / 55 % of frames of 02_02 / the sample, the truth is front on 33 / 39 %).
#: The walks cross profile from front to back there, where that lean is wrong and holds the
#: member too long; the sample crosses from back to front (frames 270-320, truth -100 -> -45),
#: where it is right, and the 2-D table, discounting it, held the back side for 50 frames.
CANONICAL_FRONT_EDGES = (0.0, 0.1, 0.3, 0.5, 0.7, 0.9)
CANONICAL_BY_FRONT = (0.407, 0.634, 0.608, 0.633, 0.654, 0.797)
CANONICAL_OVERALL = 0.624
DEFAULT_CANONICAL_PRIORS = CanonicalPriors(
    switch=CANONICAL_SWITCH_PROBABILITY, raw_side_edges=CANONICAL_RAW_SIDE_EDGES,
    raw_side_by_norm=CANONICAL_RAW_SIDE_BY_NORM, raw_side_overall=CANONICAL_RAW_SIDE_OVERALL,
    front_edges=CANONICAL_FRONT_EDGES, by_front=CANONICAL_BY_FRONT, overall=CANONICAL_OVERALL)
#: Experts asked of a mixture model's predict_hypotheses (2 states each: pose and flip). On the
#: same 28 validation renders (top-3 tables, travel weight 1/15), mean filtered heading RMS:
#: 1 expert 81.8 / 83.0 deg (evidence weight 1.0 / 0.8), 2 experts 83.0 / 85.5, 3 experts
#: 85.8 / 89.2: the other experts' poses add wrong headings more often than right ones.
#: Was 3 (2026-12-01, scripts/learn_hypothesis_priors.py --experts 1,2,3 compares them).
DEFAULT_EXPERTS = 1
_FLOOR = 1e-3                            # no evidence is ever certain


@dataclass
class Hypotheses:
    """One frame's candidate poses: poses (K, 55); log_evidence (K,) the regressor's evidence
    for each (log likelihood ratios); raw (55,) the regressor's own (first) pose; limbs (55,)
    the model's limb head's pose (a canonical member, module docstring "Limbs") or None;
    canonical: the poses are that member and its flip (:func:`canonical_hypotheses`); front:
    then the side classifier's probability that the body faces the camera's half."""

    poses: np.ndarray
    log_evidence: np.ndarray
    raw: np.ndarray
    limbs: np.ndarray | None = None
    canonical: bool = False
    front: float | None = None


def pick_member(limbs: np.ndarray, heading_deg) -> np.ndarray:
    """Of each canonical pose (55,) or (T, 55) and its front/back flip, the one whose heading
    is nearer heading_deg (scalar or (T,), degrees); same shape as limbs."""
    limbs = np.asarray(limbs, dtype=np.float64)
    h = np.radians(np.asarray(heading_deg, dtype=np.float64))
    keep = member_on_side(limbs, np.stack([np.cos(h), np.sin(h)], axis=-1))
    return np.where(np.asarray(keep)[..., None], limbs, front_back_flip(limbs))


def member_on_side(members: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Whether each pose (..., 55), not its front/back flip, has the heading nearer the
    direction (..., 2) (cos, sin): bool (...). Nearer = larger cosine with the direction
    (norms do not matter)."""
    members = np.asarray(members, dtype=np.float64)
    direction = np.asarray(direction, dtype=np.float64)
    return ((members[..., :2] * direction).sum(-1)
            >= (front_back_flip(members)[..., :2] * direction).sum(-1))


def raw_probability(norm) -> np.ndarray:
    """P(the raw pose, not its flip, is the true view | raw heading norm(s)), from
    RAW_NEARER_BY_NORM (norms beyond the last edge use the last bin)."""
    return _table(RAW_NEARER_NORM_EDGES, RAW_NEARER_BY_NORM, norm)


def deaveraged_heading(poses: np.ndarray) -> np.ndarray:
    """Poses (m, 55) with the heading the regressor was averaging towards. Where it could not
    tell a view from its flip it outputs about p (cos h, sin h) + (1 - p) (-cos h, sin h): sin h
    is kept and cos h shrinks, so the heading is pulled towards +-90 and the norm drops. Each
    hypothesis's heading takes |cos| = sqrt(1 - sin^2) back in proportion to the lost norm
    (n >= 1 keeps the pose as it is; the norm itself, the ambiguity measure, is kept). On the
    validation spirals this lowers the heading RMS of the better of (raw, flip) from 30-45 to
    19-35 degrees."""
    out = np.array(poses, dtype=np.float64, copy=True)
    c, s = out[:, 0], out[:, 1]
    n = np.hypot(c, s)
    w = np.clip(n, 0.0, 1.0)
    s_unit = s / np.maximum(n, 1.0)
    c_unit = np.where(c < 0, -1.0, 1.0) * np.sqrt(np.maximum(0.0, 1.0 - s_unit ** 2))
    h = np.arctan2(w * s + (1 - w) * s_unit, w * c + (1 - w) * c_unit)
    out[:, 0], out[:, 1] = n * np.cos(h), n * np.sin(h)
    return out


def _with_flips(poses: np.ndarray, gate: np.ndarray, limbs: np.ndarray | None = None
                ) -> Hypotheses:
    """Each pose (m, 55) with gate probability (m,) -> 2m hypotheses (pose, flip, pose, ...),
    headings de-averaged (deaveraged_heading); raw stays the regressor's first pose; limbs
    (55,) the limb head's pose or None, passed on."""
    raw = poses[0]
    poses = deaveraged_heading(poses)
    p_raw = raw_probability(heading_norm(poses))
    ratio = np.stack([p_raw / RAW_NEARER_OVERALL, (1 - p_raw) / (1 - RAW_NEARER_OVERALL)], 1)
    both = np.stack([poses, front_back_flip(poses)], axis=1).reshape(-1, poses.shape[-1])
    evidence = np.log(np.maximum(gate, _FLOOR))[:, None] + np.log(ratio)
    return Hypotheses(both, evidence.reshape(-1), raw, limbs)


def bin_index(edges, x) -> np.ndarray:
    """The bin b of each x with edges[b] <= x < edges[b + 1] (beyond the last edge: the last
    bin; below the first: the first), as the tables above are binned."""
    b = np.searchsorted(edges, np.asarray(x, float), side="right") - 1
    return np.clip(b, 0, len(edges) - 1)


def _table(edges, values, x) -> np.ndarray:
    """values[bin_index(edges, x)] (one value per edge), clipped away from 0 and 1."""
    return np.clip(np.asarray(values)[bin_index(edges, x)], _FLOOR, 1.0 - _FLOOR)


def canonical_hypotheses(raw: np.ndarray, limbs: np.ndarray, front: float,
                         priors: CanonicalPriors = DEFAULT_CANONICAL_PRIORS) -> Hypotheses:
    """The two hypotheses of a model with limbs and a side classifier: the limbs' canonical
    member (55,) and its front/back flip, whole (heading and body angles). Evidence (log
    likelihood ratios): the side of the main head's pose raw (55,) by its heading norm
    (priors.raw_side_by_norm), and the side classifier's probability front that the body
    faces the camera's half (priors.by_front); priors: the model's (:func:`canonical_priors`)."""
    limbs = np.asarray(limbs, dtype=np.float64)
    pair = np.stack([limbs, front_back_flip(limbs)])
    # The member commits to one body, so its (cos, sin) norm is ~1 even where the silhouette
    # is ambiguous; the main head's norm says how ambiguous it is, and the filters (their R
    # inflation) and the outputs (the ambiguous flag) read it from the pose.
    norm = heading_norm(raw)
    unit = pair[:, :2] / np.maximum(np.linalg.norm(pair[:, :2], axis=1, keepdims=True), 1e-9)
    pair[:, :2] = unit * norm
    evidence = np.zeros(2)
    on_raw_side = 0 if member_on_side(pair[0], deaveraged_direction(raw)) else 1
    p = _table(priors.raw_side_edges, priors.raw_side_by_norm, norm)
    evidence[on_raw_side] += np.log(p / priors.raw_side_overall)
    evidence[1 - on_raw_side] += np.log((1 - p) / (1 - priors.raw_side_overall))
    q = _table(priors.front_edges, priors.by_front, member_probability(pair[0], front))
    evidence += np.log([q / priors.overall, (1 - q) / (1 - priors.overall)])
    return Hypotheses(pair, evidence, np.asarray(raw, dtype=np.float64), limbs, canonical=True,
                      front=float(front))


def member_probability(members: np.ndarray, front) -> np.ndarray:
    """The side classifier's probability for each canonical member (..., 55) itself, from
    its probability front (...) that the body faces the camera's half: front where the
    member faces that half (cos >= 0), 1 - front elsewhere."""
    front = np.asarray(front, dtype=np.float64)
    return np.where(np.asarray(members)[..., 0] >= 0, front, 1.0 - front)


def deaveraged_direction(raw: np.ndarray) -> np.ndarray:
    """(cos, sin) (2,) of the main head's pose raw (55,) with its heading de-averaged
    (:func:`deaveraged_heading`)."""
    return deaveraged_heading(np.asarray(raw, dtype=np.float64)[None])[0, :2]


def canonical_priors(estimator) -> CanonicalPriors:
    """The priors the chain weighs an estimator's canonical pairs by: its own
    (PoseModel.canonical_priors) when it carries them, else DEFAULT_CANONICAL_PRIORS."""
    return getattr(estimator, "canonical_priors", None) or DEFAULT_CANONICAL_PRIORS


def switch_probability(estimator) -> tuple[float, float]:
    """The chain's switching probabilities for this estimator's hypotheses: canonical ones
    (a model with limbs and a side classifier; its priors' switch) switch far less often
    than a pose and its flip."""
    if getattr(estimator, "gives_canonical_pairs", False):
        return canonical_priors(estimator).switch
    return SWITCH_PROBABILITY


def evidence_weight(estimator) -> float:
    """The chain's exponent per frame on this estimator's evidence: CANONICAL_EVIDENCE_WEIGHT
    for canonical pairs (a model with limbs and a side classifier), else EVIDENCE_WEIGHT."""
    if getattr(estimator, "gives_canonical_pairs", False):
        return CANONICAL_EVIDENCE_WEIGHT
    return EVIDENCE_WEIGHT


def chain_options(estimator) -> dict:
    """FrontBackTracker's keyword arguments that depend on the estimator: its switch rates
    (switch_probability), evidence weight (evidence_weight) and the frame rate they hold at
    (its training_fps). The tracker's chains and the
    offline replays that choose their weights both take them from here."""
    return {"switch": switch_probability(estimator),
            "evidence_weight": evidence_weight(estimator),
            "reference_fps": training_fps_of(estimator)}


def propose(estimator, stacked: np.ndarray, n_experts: int = DEFAULT_EXPERTS,
            mirrored: np.ndarray | None = None) -> Hypotheses:
    """The hypotheses of one frame from a stacked descriptor (k*D,): the estimator's
    ``predict_hypotheses(stacked (N, k*D), n_experts) -> (poses (N, m, 55), probabilities
    (N, m))`` if it has one (regressor.pose_model.PoseModel: a mixture's top experts, or a
    single regressor's one pose; with ``predict_hypotheses_and_limbs``, also its limb head's
    pose), else its ``predict``; each pose and its front/back flip. An estimator with
    ``predict_frame`` (PoseModel) gives all of these and the side classifier's probability
    in one pass; with a side classifier and limbs, the hypotheses are
    :func:`canonical_hypotheses` instead. mirrored: the stacked descriptor (k*D,) of the
    frames' mirror images (tracker.mirror_limbs); its limbs are averaged into the frame's."""
    return propose_batch(estimator, np.asarray(stacked, float)[None], n_experts,
                         None if mirrored is None else np.asarray(mirrored, float)[None])[0]


def propose_batch(estimator, stacked: np.ndarray, n_experts: int = DEFAULT_EXPERTS,
                  mirrored: np.ndarray | None = None) -> list[Hypotheses]:
    """:func:`propose` for stacked descriptors (N, k*D) at once (offline evaluation);
    mirrored (N, k*D) or None as there."""
    if hasattr(estimator, "predict_frame") or hasattr(estimator, "predict_hypotheses"):
        if hasattr(estimator, "predict_frame"):
            if mirrored is not None and hasattr(estimator, "predict_frame_and_mirror"):
                # the frames and their mirror images through the limb networks at once
                poses, gate, limbs, front, mirror_limbs = estimator.predict_frame_and_mirror(
                    stacked, mirrored, n_experts)
                if limbs is not None:
                    limbs = mirror_mean(limbs, mirror_limbs)
            else:
                poses, gate, limbs, front = estimator.predict_frame(stacked, n_experts)
                limbs = _with_mirror(estimator, limbs, mirrored)
            if front is not None and limbs is not None:
                priors = canonical_priors(estimator)
                return [canonical_hypotheses(p[0], lb, f, priors)
                        for p, lb, f in zip(poses, limbs, front)]
        elif hasattr(estimator, "predict_hypotheses_and_limbs"):
            poses, gate, limbs = estimator.predict_hypotheses_and_limbs(stacked, n_experts)
            limbs = _with_mirror(estimator, limbs, mirrored)
        else:
            (poses, gate), limbs = estimator.predict_hypotheses(stacked, n_experts), None
        if limbs is None:
            limbs = [None] * len(poses)
        return [_with_flips(np.asarray(p, float), np.asarray(g, float), lb)
                for p, g, lb in zip(poses, gate, limbs)]
    raws = estimator.predict_batch(stacked)
    return [_with_flips(raw[None], np.ones(1)) for raw in raws]


def _with_mirror(estimator, limbs: np.ndarray | None, mirrored: np.ndarray | None):
    """limbs (N, 55) averaged with the estimator's limbs for the mirror images' stacked
    descriptors (tracker.mirror_limbs.mirror_mean); as they are without either."""
    if limbs is None or mirrored is None:
        return limbs
    return mirror_mean(limbs, estimator.predict_limbs(mirrored))


def propose_sequence(estimator, masks, n_experts: int = DEFAULT_EXPERTS,
                     mirror: bool = True, step: int = 1) -> list[Hypotheses]:
    """The hypotheses of one person's silhouette sequence (masks (H, W) bool, in order), as
    the tracker makes them frame by frame: each mask described (with its mirror image's
    descriptor too when tracker.mirror_limbs.sees_mirror(estimator, mirror)), stacked with
    ``step`` frames between stacked descriptors (regressor.stacking.stack_step of the
    sequence's frame rate), and :func:`propose_batch` (offline evaluation and the learning
    of priors)."""
    k = estimator.stack_depth
    if sees_mirror(estimator, mirror):
        pairs = [estimator.describe_with_mirror(m) for m in masks]
        X, M = (np.array([p[i] for p in pairs]) for i in (0, 1))
        return propose_batch(estimator, stack_frames(X, k, step=step), n_experts,
                             stack_frames(M, k, step=step))
    X = np.array([estimator.describe(m) for m in masks])
    return propose_batch(estimator, stack_frames(X, k, step=step), n_experts)


def transition_matrix(K: int, switch=SWITCH_PROBABILITY) -> np.ndarray:
    """A (K, K): states are (expert slot i, flipped f) as k = 2 i + f. The flip part is
    learned (switch = (P(raw -> flip), P(flip -> raw))); the slot part is uniform, since a
    mixture's experts are listed by gate probability, not by identity."""
    a, b = switch
    flip = np.array([[1 - a, a], [b, 1 - b]])
    m = K // 2
    return np.kron(np.full((m, m), 1.0 / m), flip)


@dataclass
class Decision:
    """The tracker's output for one frame: filtered (55,) pose of the most probable state,
    ambiguous flag (its filter's), state index and probability; the runner-up's filtered pose
    (55,) and probability when that is at least CLOSE_PROBABILITY, else None."""

    filtered: np.ndarray
    ambiguous: bool
    state: int
    probability: float
    runner_up: np.ndarray | None = None
    runner_up_probability: float | None = None


@dataclass
class _Frame:
    poses: np.ndarray            # (K, 55)
    evidence: np.ndarray         # (K,) log
    link: np.ndarray | None      # (K, K) log A + innovation log-likelihoods, None at t = 0
    heading_variance: np.ndarray  # (K,) deg^2 of travel-fused headings, NaN = the filter's
    raw: np.ndarray              # (55,) the regressor's own pose (limb input without a head)
    limbs: np.ndarray | None     # (55,) the limb head's pose (before picking), or None


@dataclass
class FrontBackTracker:
    """Per-track front/back (and expert) hypotheses over time (see the module docstring).

    filter_factory: fps -> a pose filter (tracker.pipeline.PoseFilter; its ``log_likelihoods``
    is used when it has one, else hypotheses are scored by their evidence only); fps: frames
    per second; switch: (P(raw -> flip), P(flip -> raw)) per frame; travel_weight and
    evidence_weight: exponents per frame of the travel likelihood and of the regressor's
    evidence. These per-frame figures hold at reference_fps (the rate of the sequences they
    were learned and chosen on, the model's training rate): at another fps the chain keeps
    them per second instead (:meth:`frame_rate_ratio`), so a 120 fps video's four frames
    count as one 30 fps frame did, not four times its evidence. keep_history: keep every
    frame's hypotheses for viterbi_path/smoothed (memory grows with the track; off when
    nothing needs smoothing); limb_filter_factory: fps -> a pose filter for the output's body
    angles, stepped on each frame's raw pose, or on its limb head's member that agrees with
    the decided heading (module docstring, "Limbs"); None: the chosen state's body angles.
    """

    filter_factory: Callable[[float], object]
    fps: float
    switch: tuple[float, float] = SWITCH_PROBABILITY
    travel_weight: float = TRAVEL_WEIGHT
    evidence_weight: float = EVIDENCE_WEIGHT
    reference_fps: float = DEFAULT_TRAINING_FPS
    fuse_travel: bool = True
    offset_memory: bool = True
    keep_history: bool = True
    limb_filter_factory: Callable[[float], object] | None = None
    filters: list = field(default_factory=list)
    limb_filter: object | None = None
    log_alpha: np.ndarray | None = None
    offset_beliefs: np.ndarray | None = None
    history: list[_Frame] = field(default_factory=list)
    _log_A: tuple | None = field(default=None, repr=False)

    def step(self, hypotheses: Hypotheses, travel_deg: float | None = None) -> Decision:
        """Take one frame's hypotheses and the direction of travel (degrees, None when the
        person is not moving); returns the decision."""
        poses = hypotheses.poses
        K = len(poses)
        rate = self.frame_rate_ratio
        evidence = rate * self.evidence_weight * hypotheses.log_evidence
        log_A = self._log_transitions(K)
        first = self.log_alpha is None or len(self.filters) != K
        # Each predecessor state's belief over (facing - travel), predicted to this frame
        # (rows: the states i of the last frame; the population's prior for a new track).
        if first or not self.offset_memory:
            predicted = np.tile(FACING_TRAVEL_PRIOR, (K, 1))
        elif travel_deg is None:
            # Not moving: the steps were learned on moving frames; the belief waits.
            predicted = self.offset_beliefs
        else:
            predicted = self.offset_beliefs @ offset_transition(FACING_TRAVEL_FPS / self.fps)
        travel_ll = np.zeros((K, K))          # log p(travel | state j after state i)
        fused_poses = np.broadcast_to(poses, (K,) + poses.shape)
        fused_variances = np.full((K, K), np.nan)
        offset_like = None
        if travel_deg is not None:
            headings = np.degrees(np.arctan2(poses[:, 1], poses[:, 0]))
            offset_like = offset_likelihoods(headings, travel_deg)          # (K, bins)
            travel_ll = rate * self.travel_weight * np.log(predicted @ offset_like.T)
            if self.fuse_travel and not first:
                raw_variance = self.filters[0].heading_variance
                fused_poses, fused_variances = fuse_with_priors(poses, travel_deg,
                                                                raw_variance, predicted)
        if first:
            self.filters = [self.filter_factory(self.fps) for _ in range(K)]
            stationary = np.linalg.matrix_power(np.exp(log_A), 256)[0]
            evidence = evidence + travel_ll[0]
            self.log_alpha, link = np.log(stationary) + evidence, None
            predecessor = np.zeros(K, dtype=np.int64)
        else:
            ll = np.array([f.log_likelihoods(p, v) if hasattr(f, "log_likelihoods")
                           else np.zeros(K)
                           for f, p, v in zip(self.filters, fused_poses, fused_variances)])
            link = log_A + rate * ll + travel_ll
            scores = self.log_alpha[:, None] + link
            predecessor = scores.argmax(axis=0)
            self.filters = self._continue(predecessor)
            self.log_alpha = _logsumexp(scores, axis=0) + evidence
        self.log_alpha -= _logsumexp(self.log_alpha)
        states = np.arange(K)
        poses = fused_poses[predecessor, states]
        variances = fused_variances[predecessor, states]
        beliefs = predicted[predecessor]
        if offset_like is not None:
            # The same tempering as the chain's travel evidence: windows overlap.
            beliefs = beliefs * offset_like ** (rate * self.travel_weight)
        self.offset_beliefs = beliefs / beliefs.sum(axis=1, keepdims=True)
        if self.keep_history:
            self.history.append(_Frame(poses.copy(), evidence, link, variances,
                                       np.array(hypotheses.raw, dtype=np.float64),
                                       None if hypotheses.limbs is None
                                       else np.array(hypotheses.limbs, dtype=np.float64)))
        outputs = [f.step(pose, heading_variance=None if np.isnan(v) else float(v))
                   for f, pose, v in zip(self.filters, poses, variances)]
        prob = np.exp(self.log_alpha)
        order = np.argsort(-prob)
        best = int(order[0])
        filtered = outputs[best][0]
        if self.limb_filter_factory is not None:
            if self.limb_filter is None:
                self.limb_filter = self.limb_filter_factory(self.fps)
            source = (hypotheses.raw if hypotheses.limbs is None
                      else pick_member(hypotheses.limbs, heading_deg(filtered[None])[0]))
            # The limb filter measures the decided heading, not the source's: its R couples
            # heading and joints, and a heading innovation would pull the limbs.
            source = with_body_angles(filtered, source)
            filtered = with_body_angles(filtered, self.limb_filter.step(source)[0])
        decision = Decision(filtered, bool(outputs[best][1]), best, float(prob[best]))
        if K > 1 and prob[order[1]] >= CLOSE_PROBABILITY:
            decision.runner_up = outputs[order[1]][0]
            decision.runner_up_probability = float(prob[order[1]])
        return decision

    @property
    def frame_rate_ratio(self) -> float:
        """reference_fps / fps: the share of a reference frame one of this video's frames is
        (0.25 at 120 fps for a 30 fps reference); evidence, travel and the filters'
        likelihoods are tempered by it (exponents), and the switch probabilities are those
        of that share of a frame (:meth:`frame_switch`). 1 at the reference rate."""
        return self.reference_fps / self.fps

    @property
    def frame_switch(self) -> tuple[float, float]:
        """The switch probabilities per frame of this video: 1 - (1 - p)^ratio of the
        reference frame's p, the same chance of switching per second."""
        rate = self.frame_rate_ratio
        if rate == 1.0:
            return tuple(self.switch)
        return tuple(float(-np.expm1(rate * np.log1p(-p))) for p in self.switch)

    def _log_transitions(self, K: int) -> np.ndarray:
        """log A (K, K) for the current switch probabilities, computed once."""
        key = (K, tuple(self.switch), self.fps, self.reference_fps)
        if self._log_A is None or self._log_A[0] != key:
            self._log_A = (key, np.log(transition_matrix(K, self.frame_switch)))
        return self._log_A[1]

    def _continue(self, predecessor: np.ndarray) -> list:
        """Filters for the new states: state j continues predecessor[j]'s filter (a copy when
        two states continue the same one; copies are made before any filter steps)."""
        used, out = set(), []
        for i in predecessor:
            f = self.filters[int(i)]
            out.append(_clone(f) if int(i) in used else f)
            used.add(int(i))
        return out

    def viterbi_path(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """The most probable state sequence (n,) int over the frames so far, or over
        history[start:stop] alone (its first frame taken as a track's first)."""
        frames = self.history[start:stop]
        if not frames:
            return np.zeros(0, dtype=np.int64)
        first = frames[0]
        K = len(first.poses)
        log_A = self._log_transitions(K)
        delta = np.log(np.linalg.matrix_power(np.exp(log_A), 256)[0]) + first.evidence
        back = []
        for frame in frames[1:]:
            scores = delta[:, None] + frame.link
            back.append(scores.argmax(axis=0))
            delta = scores.max(axis=0) + frame.evidence
        path = [int(delta.argmax())]
        for pointers in reversed(back):
            path.append(int(pointers[path[-1]]))
        return np.array(path[::-1], dtype=np.int64)

    def chosen_poses(self, start: int = 0, stop: int | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
        """The hypotheses (n, 55) on the Viterbi path of history[start:stop] (the smoother's
        input) and their heading variances (n,) deg^2 (NaN: the filter's own)."""
        frames = self.history[start:stop]
        path = self.viterbi_path(start, stop)
        return (np.array([frame.poses[s] for frame, s in zip(frames, path)]),
                np.array([frame.heading_variance[s] for frame, s in zip(frames, path)]))

    def smoothed(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """RTS-smoothed poses (n, 55) of the Viterbi path's hypotheses (``--smooth``): of the
        whole track, or of history[start:stop] as if the track were those frames alone (the
        fixed-lag smoothing of tracker.fixed_lag). With a limb_filter_factory, the body angles
        are its RTS smoothing of the raw poses (of the limb head's members on their most
        probable chain given the smoothed heading when every frame has them, as a model's
        frames all do: tracker.member_path), with the smoothed heading as theirs."""
        frames = self.history[start:stop]
        poses, variances = self.chosen_poses(start, stop)
        out = self.filter_factory(self.fps).rts_smooth(poses, heading_variance=variances)
        if self.limb_filter_factory is not None and len(out):
            raws = np.array([frame.raw for frame in frames])
            if all(frame.limbs is not None for frame in frames):
                raws = members_over_time(np.array([frame.limbs for frame in frames]),
                                         heading_deg(out), self.frame_rate_ratio)
            raws = with_body_angles(out, raws)          # the decided heading, as online
            out = with_body_angles(out, self.limb_filter_factory(self.fps).rts_smooth(raws))
        return out


def with_body_angles(pose: np.ndarray, limbs: np.ndarray) -> np.ndarray:
    """pose (..., 55) with its 53 body angles (entries 2..54) taken from limbs (..., 55); the
    heading (cos, sin) is pose's."""
    out = np.array(pose, dtype=np.float64, copy=True)
    out[..., 2:] = np.asarray(limbs)[..., 2:]
    return out


def _clone(f):
    """An independent copy of a filter: its own ``copy()`` when it has one (PoseKalmanFilter's
    copies two arrays), else a deep copy."""
    return f.copy() if hasattr(f, "copy") else copy.deepcopy(f)


def _logsumexp(x: np.ndarray, axis=None) -> np.ndarray:
    top = np.max(x, axis=axis, keepdims=True)
    out = top + np.log(np.exp(x - top).sum(axis=axis, keepdims=True))
    return out.squeeze(axis) if axis is not None else out.reshape(())
