#pragma once
// Relocalization against a prior map without a manual initial guess (issue #6 item 2; paper sec.
// II-E, ../shared/paper.md item 11): recovers T_prior_world, the current run's world frame in the
// earlier run's (6 DoF, the paper's Gamma of eq. 6).
//
// Method (paper sec. II-E: "the IMU magnetometer helps estimate relative angles theta_z. When GPS
// data is available, absolute coordinates are used ... If GPS data is unavailable, key frame sampling
// and NDT matching are performed between the current point cloud and the prior map with the key
// frames. Key frames are typically sampled within twice the moving distance ... Three high-resolution
// poses are selected for precise matching"):
//  0. Structure (min_attempt_structure_points): a local map of ground alone ends the attempt at once
//     (kTooLittleStructure); the caller tries again after more motion.
//  a. Candidates (sample_candidates): with a position prior (a GNSS fix moved into the prior frame),
//     the prior keyframes within 2 d + k sigma of it horizontally, d the distance moved so far;
//     without one, every prior keyframe.
//  b. Appearance: every prior keyframe's ORB descriptors are in one LSH index (bit sampling,
//     vote_lsh: tables of key_bits bits drawn with a fixed seed, built once per prior map by a
//     counting sort); each current descriptor votes once for every candidate keyframe holding a
//     descriptor within vote_tie_bits of the nearest candidate descriptor found (near-ties: the copies
//     of a repeated place all get the vote; nearest-only votes gave the sim's copy, 3 bits further, 4
//     of the original's 57; with a position prior the other keyframes' descriptors are not read: they
//     are other places, and skipping them cut the outdoor vote from ~15 to ~4 ms). Candidates are
//     ranked by votes and the top_k (no two neighbouring keyframes) go on, each matched with the
//     current keyframe (estimation::ExactMatcher, ratio test; an attempt matches a keyframe once and
//     keeps the matches for its later steps).
//  c. Geometry: per candidate, RANSAC (estimation::PoseRansac) over the candidate's keypoints with
//     depth (moved to the prior frame) and the current keypoints gives T_prior_cam, hence
//     T_prior_world = T_prior_cam * T_world_cam^-1. With a yaw prior, hypotheses whose relative yaw
//     differs by more than yaw_gate_sigmas sigma + yaw_gate_margin_rad are rejected. Hypotheses
//     within dedup_m / dedup_rad of a better one are merged. A refined pose is backed by the ORB seed
//     nearest it among those whose coarse NDT ended on it and within max_ndt_correction of it (step
//     e judges that seed; the verification excludes every ORB seed keyframe that ended on it). When no
//     candidate gives one (the paper's method), NDT is seeded with the candidates' keyframe poses ("the
//     initial parameters are set to the pose of the current key frame"), rotated by the yaw prior when there
//     is one. A position prior adds seeds of its own: with a yaw prior one (the paper's GNSS + magnetometer
//     case), without one a sweep of yaw_sweep_steps yaws when ORB gave nothing.
//  d. NDT (recon::NdtAligner, Magnusson 2009) of the current local cloud, moved by each hypothesis,
//     against the prior: the whole prior's targets, built once (prepare_targets, when every cloud is
//     in memory), else the prior points around it (PriorMap::points_near: the cloud's extent +
//     target_margin_m about its moved centroid), coarse to fine over ndt_coarse.resolutions_m. A coarse
//     result seeds the next stage when it converged or only stopped early (line search on a voxel-face jump,
//     out of iterations) and covers min_inlier_ratio of the cloud; the coarse levels have no degeneracy test
//     (at 1-2 m voxels the ground dominates the Hessian; the fine stage judges). The keep_best (3)
//     best by NDT score are aligned again at ndt_fine.resolutions_m ("three high-resolution poses");
//     the best of those is the answer. The fine stage's source is the local map's structure points
//     (off horizontal planes, structure_points.hpp) plus at most fine_ground_share of their count of
//     the rest, when it has min_structure_points of them: the ground's pull towards its voxel means
//     then no longer outweighs the walls along x, y and yaw.
//  d'. ORB refinement (RelocalizerConfig::orb_refine): a fine fit that converged but that NDT calls
//     degenerate (the structure in view leaves x, y or yaw weak) is refined by a pose-only fit of
//     the current keyframe's ORB keypoints matched with the prior keyframes near the fitted camera;
//     it replaces the NDT pose only when that fit pins every direction and NDT scores it about as
//     well (the geometry agrees), else the fit stays rejected as degenerate. A converged fit that
//     step e accepts is then polished the same way (orb_refine_converged; a move of at most
//     10 cm / 1 deg, within the priors' gates; an ORB fit beyond that move rejects the fit,
//     orb_polish_rejects_beyond_move): the ORB fit over the nearby keyframes measures the
//     pose against the map where the camera is, which the NDT fit over the whole local map can miss
//     by a few tenths of a degree (sim lab: 3-4.5 cm at the camera). The verdict is NDT's; the
//     polished pose is returned only when it passes step e's pose-dependent tests too.
//  e. Acceptance, so that a pose is returned only when it is unambiguous (0 false relocalizations
//     is an acceptance goal of the issue): the fine NDT converged (not degenerate, or degenerate and
//     ORB-refined, step d'), its inlier ratio
//     is at least min_inlier_ratio, it agrees with the priors given (yaw gate; the position within
//     position_gate_sigmas sigma + position_gate_margin_m) and, for an ORB seed, NDT moved it by at
//     most max_ndt_correction_m / _rad; the current keyframe's ORB matches with the prior keyframes
//     near the fitted camera agree with the fit (NDT alone cannot tell symmetric places apart: in
//     the sim lab it put the north bench row onto the south one, 17.8 m / 180 deg off, at an inlier
//     ratio of 0.93) -- for an ORB seed, keyframes other than the seed and its nms_keyframes
//     neighbours (whose matches made the pose: not independent evidence); when no such keyframe is
//     near, "not verified"; and its score per source point beats that of the best rival more than
//     distinct_m or distinct_rad away that the priors allow, at the fine and at the coarse
//     resolution, by min_score_margin (relative); the scores are taken over the structure points
//     alone when there are min_structure_points of them (every rival at its own pose): a ground plane
//     fits a wrong pose as well as the right one, which outdoors kept margins over all points at
//     0.01-0.23 for correct fits. Rivals: the other refined hypotheses, and always
//     NDT from the best turned 180 deg about the vertical through the local map's centroid, and
//     from the first RANSAC pose distinct from the fit among the next rival_scan ranked candidates
//     with a vote, away (> verify_radius_m) from the fitted camera (a repeated place: the second
//     vote cluster), else from the best-voted candidate keyframe's pose away from the fit; for a weak
//     fit (step d') also the ORB rivals: the poses that RANSAC and the ORB refinement give at the
//     best-voted prior keyframes away from the fit (orb_rival_keyframes; along its weak direction
//     the fit stands on appearance, which can repeat where the geometry does too); and for a weak
//     fit the rivals within verify_radius_m of its camera are judged by the keypoints
//     (orb_judges_near_rivals: one its own nearby keyframes do not support is refuted). A
//     repeated place is found mainly through the hypotheses: with near-tie votes its copies' keyframes
//     reach the top_k, RANSAC puts a hypothesis on each copy and the keep_best refinement scores them
//     against each other (copies closer than verify_radius_m too, which the scan skips). Measured
//     (tests/recon/test_relocalizer.cpp, sim lab, three segments and a copy 6 m along x): margin
//     -0.02 (fine 0.02-0.03), kAmbiguous, with the copy's descriptors 3 bits off, bit-identical, or
//     2.5 m away; a position prior of 0.5 or 1 m sigma (gate 3 sigma + 1 m < 6 m) picks the bay it
//     points at (1.5 / 0.6 cm), the original or the copy. When no rival gave a pose the priors allow,
//     the margin is unknown: rejected (kAmbiguous, fail closed) unless both a position and a yaw prior
//     pin the pose. With priors, fits that contradict them are not chosen while one that agrees exists.
//     Otherwise the result says "not localized" with a reason, and the caller tries again after more
//     motion. Limitations: at most top_k (8) candidates and keep_best (3) refined poses: more copies
//     of one place than that are not all scored, but one rival suffices for kAmbiguous; a copy whose
//     descriptors differ from the query's by more than vote_tie_bits beyond the other copy's gets
//     nearest-only votes (few) and is found only by the rival scan (with a position prior only among
//     the candidates: a copy outside 2 d + k sigma is no candidate and cannot take votes).
//
// Scores: NDT's score of eq. 6.9 summed over the (same, subsampled) source cloud, divided by its
// point count, so hypotheses are compared on the same cloud at the same resolution.
//
// Memory: create() sizes the current-keyframe matcher and the attempt's match cache (48 keyframes x
// max_features matches, 12 B each: 460 kB at 800), RANSAC, the correspondence buffers, the source buffer
// (max_source_points), both NDT aligners (one target per level: coarse 2 x 65536 voxels, fine 2 x 262144,
// ~130 MB, for gathered targets; a target gathered once serves every hypothesis near it) and the structure
// scores' NDT targets (two, one per resolution, at most 65536 voxels each, ~13 MB each), and step d''s
// pose-only refiner and keypoint marks (max_features). relocalize() runs off the control loop and
// allocates: the prior LSH index (prepare(), once per prior map: per feature a copy of its descriptor
// (32 B), its keyframe and a query mark (4 B each) and 8 B per table (its id and keyframe in bucket
// order), plus 4 (2^key_bits + 1) B of offsets per table; with 4 x 16-bit tables ~12 MB for the lab's 158k
// features, the build's 4 B per feature of key scratch freed), the whole prior's NDT targets
// (prepare_targets(), once per prior map: ~200-240 B per voxel of capacity, at most twice the voxels
// occupied, within max_whole_prior_voxels; the sim outdoor prior's 3.6M thinned points occupy 89k
// voxels over 2, 1, 0.5 and 0.25 m: 18-42 MB), the current
// keyframe's LSH tables (FLANN allocates them on every build), the per-prior-keyframe vote and position
// tables (first call), the prior target cloud (grows to the largest points_near answer, then reused), the
// structure split (a voxel hash over the local map, and the structure / fine-source buffers, reused), the
// prior map's cloud loads and the result's message.

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/lsh_matcher.hpp"
#include "hwr/estimation/pose_ransac.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/recon/ndt.hpp"
#include "hwr/recon/prior_map.hpp"

namespace hwr::recon {

// A position prior in the prior frame (a GNSS fix converted by the caller), 1-sigma horizontal.
struct PositionPrior {
  bool valid = false;
  Eigen::Vector3d p_prior_m = Eigen::Vector3d::Zero();
  double sigma_m = 0;
};

// Step a. Indices of the prior keyframes (camera positions p_prior_cam_m, prior frame, z up) that
// are candidates: with a valid position prior those whose horizontal distance to it is at most
// 2 * moved_m + sigma_factor * sigma_m (paper: "sampled within twice the moving distance"), nearest
// first (ties by index); without one, all of them in index order. Pure; `out` is overwritten.
void sample_candidates(const std::vector<Eigen::Vector3d>& p_prior_cam_m, const PositionPrior& prior,
                       double moved_m, double sigma_factor, std::vector<int>* out);

struct RelocalizerConfig {
  // a. candidates
  double candidate_sigma_factor = 3.0;
  // b. appearance. vote_lsh: the index over every prior descriptor, small and coarse (4 tables of
  // 16-bit keys, no multi-probe: a vote needs no high recall; FLANN's 12 x 20-bit, 2-probe index took
  // 1.5 s to build and 1 s to query over the lab's 158k prior descriptors). Only tables (1-16),
  // key_bits (1-20) and multi_probe (0-2) are used; the distances are vote_max_distance and
  // vote_tie_bits. lsh: the current keyframe's 800, matched with each selected candidate.
  estimation::LshConfig vote_lsh = [] {
    estimation::LshConfig c;
    c.tables = 4;
    c.key_bits = 16;
    c.multi_probe = 0;
    return c;
  }();
  // The current keyframe matched with one prior keyframe at a time (steps c, d', e): exact 2-NN
  // (estimation::ExactMatcher, exact_matcher.hpp) or, when false, FLANN's LSH with `lsh` (the
  // relocalizer's matcher until 2026-12-02). Either way the ratio test and max distance are lsh's.
  bool exact_matching = true;
  estimation::LshConfig lsh;
  int vote_max_distance = 50;  // Hamming distance of a vote (nearest prior descriptor)
  // A current descriptor votes for every prior keyframe holding a descriptor within this many bits
  // of the nearest one (near-ties: a repeated place's copies all get the vote); 0: nearest only.
  // Both in [0, 256]. Votes are per query descriptor: a prior descriptor near several query
  // descriptors adds once for each.
  int vote_tie_bits = 8;
  int min_votes = 15;     // fewer: the candidate does not go to RANSAC
  int top_k = 8;          // candidates that go on to RANSAC (and fallback seeds)
  int nms_keyframes = 1;  // ... no two within this many keyframe indices of each other
  // e. the second vote cluster: at most this many further ranked candidates (any vote, more than
  // verify_radius_m from the fitted camera) are matched and RANSAC'd looking for a rival pose.
  int rival_scan = 8;
  // c. geometry
  estimation::PoseRansacConfig ransac = [] {
    estimation::PoseRansacConfig c;
    c.max_iterations = 300;
    return c;
  }();
  int min_orb_inliers = 30;
  double yaw_gate_sigmas = 3.0;
  double yaw_gate_margin_rad = 5.0 * 3.14159265358979323846 / 180.0;
  double dedup_m = 0.1, dedup_rad = 2.0 * 3.14159265358979323846 / 180.0;
  bool fallback_keyframe_seeds = true;  // the paper's NDT-from-keyframe-poses when ORB gives nothing
  int yaw_sweep_steps = 12;             // position prior without yaw prior and without ORB hypotheses
  // d. NDT
  NdtConfig ndt_coarse = [] {
    NdtConfig c;
    c.resolutions_m = {2.0, 1.0, 0.0, 0.0};
    // No degeneracy test at the coarse levels: they only seed the fine stage, and at 1-2 m voxels a
    // ground plane dominates the Hessian (outdoors the smallest/largest eigenvalue ratio was
    // 0.0004-0.0097, median 0.0018, at fits the fine stage then confirmed).
    c.degenerate_eigenvalue_ratio = 0.0;
    c.translation_epsilon_m = 0.002;
    c.rotation_epsilon_rad = 0.0005;
    c.max_source_points = 20'000;
    c.max_target_points = 2'000'000;
    // At 1-2 m a target ball of radius r holds at most ~4.2 r^3 voxels: 65536 covers r <= 25 m
    // (the ball is the local map's extent + target_margin_m + 1 m) at a quarter of the default's
    // memory (the aligner keeps one target per level).
    c.max_target_voxels = 65'536;
    c.target_per_level = true;  // every hypothesis near one gather reuses its targets
    return c;
  }();
  NdtConfig ndt_fine = [] {
    NdtConfig c;
    // Measured on the sim lab (tests/recon/test_relocalizer.cpp): ending at 0.25 m the lab-revisit
    // run's frame came out within 0.3-0.6 cm / 0.03-0.06 deg, ending at 0.125 m within 1.1-2.0 cm /
    // 0.1-0.2 deg (the 2 cm map voxels and depth noise of two runs at that scale).
    c.resolutions_m = {0.5, 0.25, 0.0, 0.0};
    // 0.5 mm / 0.03 deg: finer than the goal (3 cm / 0.3 deg); at 1e-4 the line search failed on
    // voxel-face jumps in 3 of 8 attempts.
    c.translation_epsilon_m = 5e-4;
    c.rotation_epsilon_rad = 5e-4;
    c.degenerate_eigenvalue_ratio = 0.0125;
    c.max_source_points = 20'000;
    c.max_target_points = 2'000'000;
    c.target_per_level = true;
    return c;
  }();
  // d'. ORB refinement of a fine fit that NDT leaves weak (failure kDegenerate: outdoors the
  // structure in view often does not pin x, y and yaw, and the ground's pull then biases the fit by
  // 4-14 cm). The current keyframe's ORB keypoints are matched with the orb_refine_keyframes prior
  // keyframes nearest the fitted camera (within verify_radius_m, axes within verify_max_angle_rad),
  // gated at the NDT pose (orb_refine_gate_px x the octave's scale, depth within
  // orb_refine_depth_frac), one correspondence per current keypoint (the nearest keyframe's), RANSAC
  // over them (estimation::PoseRansac, config `ransac`: the wide gate lets mismatches through), then a
  // pose-only fit from the consensus (estimation::MotionOnlyRefiner: reprojection and depth residuals,
  // Huber). It replaces the NDT pose when it has orb_refine_min_inliers inliers, its covariance pins
  // every direction (largest position and rotation sigma at most orb_refine_max_sigma_m / _rad), it
  // moved the fit by at most orb_refine_max_move_m / _rad, and the geometry agrees: the NDT score
  // per point of the structure points and of the whole fine source (the ground: z, roll, pitch) at the
  // refined pose is at least (1 - orb_refine_max_score_loss) of that at the NDT pose (along a weak
  // direction NDT's cost is flat; a pose that contradicts the geometry scores less). Only the RANSAC
  // inliers go into the pose-only fit. Step e then judges the refined fit as any other, but for its
  // ORB seed (see max_ndt_correction) and its ORB verification, which uses keyframes the refinement
  // also used (the 200-inlier fit stands in for it). Only tried with min_structure_points structure
  // points: texture alone can repeat (the sim's outdoor ground pattern gave consistent ORB fits 4.09 m
  // off; on a ground-only local map one was accepted).
  bool orb_refine = true;
  int orb_refine_keyframes = 5;
  double orb_refine_gate_px = 60.0;
  double orb_refine_depth_frac = 0.3;
  double orb_refine_max_move_m = 1.0;
  double orb_refine_max_move_rad = 5.0 * 3.14159265358979323846 / 180.0;
  // A place that recurs elsewhere explains only part of the keyframe: 50 starts outdoors, refined
  // fits 12.5 m off (a place of the prior 12.3 m away matching in geometry and texture) had 47-110
  // inliers at sigma 0.34-0.58 cm, right ones 177-424 at 0.13-0.26 cm. With the local map cropped to
  // 8 m about the camera (as RelocalizationWorker sends it) one such fit had 183 inliers (sigma
  // 0.28 cm, accepted 12.26 m off); the right ones of that run had 156 (one start), then 204-4xx.
  int orb_refine_min_inliers = 200;
  double orb_refine_max_sigma_m = 0.01;
  double orb_refine_max_sigma_rad = 0.2 * 3.14159265358979323846 / 180.0;
  double orb_refine_max_score_loss = 0.1;
  // The same refinement of the converged fine fit step e accepted (only with orb_refine and
  // min_structure_points), with the same gates but a tighter move; the polished pose must pass step
  // e's pose-dependent tests again (priors' gates, the ORB seed's max_ndt_correction, the ORB check),
  // else NDT's pose is returned. The score margin is the NDT fit's: NDT's pose maximises that score,
  // so taken again at the polished pose (until 2026-12-02) it was lower by construction and refused
  // polishes of fits 4-7 cm off; within the polish's move no rival is near and refine_by_orb's
  // agreement test holds. It changes the pose, never whether it is accepted (but for
  // orb_polish_rejects_beyond_move). Measured (hwr-bench
  // reloc --scenes lab --starts 50 --seed 1,
  // --orb-refine weak vs all): lab 90 % -> 100 % within 3 cm / 0.3 deg, error (b) max
  // 4.4 cm / 0.42 deg -> 0.42 cm / 0.08 deg.
  bool orb_refine_converged = true;
  double orb_refine_converged_max_move_m = 0.1;
  double orb_refine_converged_max_move_rad = 1.0 * 3.14159265358979323846 / 180.0;
  // The polish's inlier minimum. For a weak fit the ORB fit decides the pose along the weak
  // direction, so orb_refine_min_inliers keeps it from standing on a partial match with a copy of
  // the place (12.3 m away outdoors); a polish only moves a fit that step e already accepted, by at
  // most 10 cm / 1 deg, and faces step e's tests again. A lab start whose converged fit (eigenvalue
  // ratio 0.0134, just over the degeneracy test's 0.0125) was 3.45 cm off had 162-166
  // correspondences with the 5 nearest prior keyframes, so 200 refused its polish.
  int orb_refine_converged_min_inliers = 100;
  // A polish refused because the ORB fit (its inlier and sigma gates passed) lies beyond the move
  // limit means the keypoints near the camera contradict the NDT fit: the attempt is rejected
  // (kNotVerified) instead of returning NDT's pose. Neither the priors' gates nor NDT's score of the
  // ORB pose is asked: the two measurements disagree either way (fail closed).
  bool orb_polish_rejects_beyond_move = true;
  int max_source_points = 8'000;    // the local cloud is subsampled (stride) to at most this
  int max_target_points = 150'000;  // the prior target is subsampled (stride) to at most this
  // The coarse stage (1-2 m voxels, seeds only) takes every k-th source point, at most
  // coarse_source_points, and every k-th target point, at most coarse_target_points (gathered
  // targets only): at those voxel sides more points change the Gaussians little and cost linearly
  // (hwr-bench reloc --verbose prints the NDT time per attempt). With the whole prior's targets
  // the coarse Newton iterations were the stage's cost: 3000 -> 1500 source points took the outdoor
  // both-priors row's coarse stage from 34 to 17 ms per successful attempt (median, 50 starts) with the
  // same successes and errors (docs/relocalization.md "Speed II").
  int coarse_source_points = 1'500;
  int coarse_target_points = 100'000;
  double target_margin_m = 2.0;  // beyond the local cloud's extent
  // NDT targets of the whole prior (prepare_targets): when every prior cloud is in memory, each
  // resolution's voxel Gaussians are built once over all of it, and no attempt gathers points or
  // builds a target again (the prior does not change while the robot relocalizes). Otherwise, or
  // when false, each hypothesis gathers the prior points about it (target_margin_m, max_target_points,
  // coarse_target_points) and builds its targets (hwr-bench reloc, both priors outdoors: building them
  // was 27 % of relocalize() and gathering the points 10 %).
  bool whole_prior_targets = true;
  // Voxels the whole prior's targets may allocate, all resolutions together (~200-240 bytes each:
  // 10^6 ~ 0.24 GB); a prior that needs more gathers per query. The sim outdoor prior allocates
  // ~0.13-0.19 x 10^6 for its 89k occupied voxels.
  int64_t max_whole_prior_voxels = 1'000'000;
  int keep_best = 3;  // paper: "three high-resolution poses"
  // e. acceptance
  double min_inlier_ratio = 0.7;
  double min_score_margin = 0.2;  // (best - competitor) / best, scores per source point
  // The margin is taken over the local map's structure points (off horizontal planes,
  // src/structure_points.hpp) when it has at least min_structure_points of them, else over all
  // points: outdoors the ground is most of the map and fits a wrong pose as well as the right one
  // (sim outdoor: margins over all points 0.01-0.23 for correct fits).
  // 200 since 2026-12-02 (300 before): in hwr-bench reloc the starts that never localized outdoors
  // mostly walked through places with 195-292 structure points; with both gates at 200 the outdoor
  // rows went from 94/94/96/96 % to 98/98/98/98 % (seed 1) and from 88/88/92/92 % to 94/94/98/98 %
  // (seed 2), 0 false and 0 inaccurate in both, the 40 cross-scene starts still not localized, the
  // medians unchanged; 150 gained nothing more on seed 1 (docs/relocalization.md).
  int min_structure_points = 200;
  // An attempt whose local map has fewer structure points than this ends at once
  // (kTooLittleStructure), before any matching or NDT: the ground alone leaves x, y and yaw free, so
  // NDT calls every fit degenerate, the ORB refinement needs min_structure_points, and the ground's
  // texture can repeat (hwr-bench reloc --verbose: such attempts outdoors took 0.1-0.4 s each and
  // none was accepted; with the gate off, seed 1: no start more localized, medians 0.233 -> 0.579 s
  // without GNSS). 0: off.
  int min_attempt_structure_points = 200;
  double structure_voxel_m = 0.5;
  double structure_min_normal_z = 0.8;
  // With that much structure the fine NDT (step d) aligns the structure points and at most this
  // share of their count of the rest (ground), so the ground does not outweigh them along x, y, yaw.
  double fine_ground_share = 0.5;
  double distinct_m = 0.5, distinct_rad = 10.0 * 3.14159265358979323846 / 180.0;
  double max_ndt_correction_m = 0.3, max_ndt_correction_rad = 3.0 * 3.14159265358979323846 / 180.0;
  double position_gate_sigmas = 3.0, position_gate_margin_m = 1.0;
  // ORB rivals of a weak (step d', ORB-refined) fit: its position along the direction the geometry
  // leaves free rests on appearance, which can repeat (a long wall: the sim's textures tile every
  // 2.6-4.1 m). The orb_rival_keyframes best-voted prior keyframes more than verify_radius_m from
  // the fitted camera, looking the same way (verify_max_angle_rad), at least orb_rival_spacing_m
  // apart, are matched with the current keyframe (RANSAC) and the pose refined by ORB there
  // (orb_refine's correspondence gates; no sigma, move or NDT-agreement test); a distinct pose the
  // priors allow with at least orb_rival_min_inlier_fraction of the fit's refinement inliers is a
  // rival in the structure margin (not an evaluated rival for margin_known: no NDT result). The
  // fraction stays low: the copy of the outdoor false fit had 244 inliers against the fit's 334
  // (another viewpoint), and along the weak direction the structure margin cannot part them, so
  // this count is what the veto rests on. 0: off.
  int orb_rival_keyframes = 6;
  double orb_rival_spacing_m = 2.0;
  double orb_rival_min_inlier_fraction = 0.5;
  // The geometric rivals near a weak fit, judged by its keypoints: when the prior keyframes near the
  // fit, their matches ungated, agree on the fit (RANSAC), a hypothesis or rival seed whose camera is
  // within verify_radius_m of the fitted camera stays in the structure margin only if the keyframes
  // near its own camera, ungated, give a distinct pose the priors allow with
  // orb_rival_min_inlier_fraction of the fit's inliers (it competes at that pose); otherwise its
  // keypoints refute it (counters.rivals_refuted_by_orb). Along the weak direction NDT stops where
  // the ground's pull ends, and there the structure margin cannot part that pose from the fit
  // (outdoor f5748: 1.11 m off, margin 0.18). A copy within the radius keeps its own keyframes'
  // support and still competes (test). false: every rival competes as it is.
  bool orb_judges_near_rivals = true;
  // ORB verification of the best fit: of the verify_keyframes prior keyframes nearest its camera
  // (within verify_radius_m, optical axes within verify_max_angle_rad), one must have at least
  // min_verified_matches LSH matches with the current keyframe that its pose reprojects within
  // verify_px x the octave's scale and whose depths agree within verify_depth_frac.
  bool require_orb_verification = true;
  int verify_keyframes = 3;
  double verify_radius_m = 3.0, verify_max_angle_rad = 60.0 * 3.14159265358979323846 / 180.0;
  double verify_px = 4.0, verify_depth_frac = 0.1;
  int min_verified_matches = 25;
};

struct RelocalizationQuery {
  const estimation::FrameFeatures* features = nullptr;            // the latest keyframe's
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  // its pose, current world
  PointsView local_map_world;  // the current local map's points, current world frame
  double moved_m = 0;          // distance moved so far in this run
  PositionPrior position;      // p_prior_m: the current camera position in the prior frame
  bool yaw_valid = false;      // relative yaw of the worlds: yaw of R_prior_world about z
  double yaw_prior_rad = 0, yaw_sigma_rad = 0;
};

enum class RelocalizationReason : uint8_t {
  kLocalized,
  kInvalidQuery,        // see the message
  kTooFewLocalPoints,   // the local map is too small for NDT
  kTooLittleStructure,  // the local map is ground only (min_attempt_structure_points)
  kNoCandidates,        // no prior keyframe near the position prior
  kNdtFailed,           // no hypothesis converged
  kLowInlierRatio,      // the best fit leaves too much of the local map unexplained
  kPriorDisagreement,   // the best fit contradicts the yaw / position prior or its ORB seed
  kAmbiguous,           // another, distinct pose fits almost as well
  kNotVerified,         // the current keyframe's ORB features disagree with the best fit
  kPriorMapError,       // a prior cloud could not be read (see the message)
};
const char* relocalization_reason_name(RelocalizationReason r);

struct RelocalizationCounters {
  int candidates = 0;         // after sampling
  int appearance_ranked = 0;  // candidates with >= min_votes
  int ransac_runs = 0;
  int ransac_hypotheses = 0;  // RANSAC poses with enough inliers (before the yaw gate, dedup)
  int yaw_rejected = 0;
  int fallback_seeds = 0;     // keyframe / position-prior seeds
  int ndt_runs = 0;           // coarse and fine
  int ndt_converged = 0;      // coarse
  int64_t target_points = 0;  // largest prior target used
  int rival_seeds = 0;        // step e: NDT runs from rival seeds (180 deg turn, second cluster, keyframe)
  int orb_rival_tests = 0;    // step e: prior keyframes matched for ORB rivals of a weak fit
  int orb_rivals = 0;         // ... that gave a distinct ORB-refined pose (a rival in the structure margin)
  int rivals_refuted_by_orb = 0;  // step e: geometric rivals near a weak fit that its keypoints refute
};

struct RelocalizationResult {
  bool localized = false;
  Eigen::Isometry3d T_prior_world = Eigen::Isometry3d::Identity();  // valid when localized
  // The best fit that step e judged, also when it was rejected (for diagnosis and benches; never a
  // pose to use): valid when best_fit_valid. For a polished fit (orb_refine_converged) the NDT pose;
  // T_prior_world is then the polished one.
  Eigen::Isometry3d T_prior_world_best_fit = Eigen::Isometry3d::Identity();
  bool best_fit_valid = false;
  RelocalizationReason reason = RelocalizationReason::kNdtFailed;
  std::string message;  // one line a person can read, with the numbers behind the reason
  RelocalizationCounters counters;
  // The fine scores (per source point) of the keep_best hypotheses, best first; unused are 0.
  std::array<double, 3> best_scores{0, 0, 0};
  double best_inlier_ratio = 0;
  int structure_points = 0;  // the local map's structure points (off horizontal planes; steps 0, d, e)
  // Relative margin of the best fine score over the best distinct rival's the priors allow (fine and
  // coarse, the smaller). 1 when rivals were evaluated and none ended distinct from the best.
  double score_margin = 0;
  int rivals_evaluated =
      0;  // rival NDT results the priors allow (distinct or back on the best); not ORB rivals
  bool margin_known = false;      // rivals_evaluated > 0; when false the margin is unknown (see step e)
  int verify_keyframes_used = 0;  // prior keyframes the ORB verification checked (seeds excluded)
  // Step e's ORB rivals of a weak fit (counters.orb_rivals): the most inliers one had, and whether
  // the rival closest to the best in the structure margin (the level that decided) was one of them.
  int orb_rival_max_inliers = 0;
  bool closest_rival_orb = false;
  bool best_from_orb = false;
  int best_orb_inliers = 0;
  int verified_matches = 0;  // ORB verification of the best fit (step e)
  // Step d': the best fit's pose came from the ORB refinement of its fine NDT fit, a degenerate one
  // (orb_refined_weak) or the accepted converged one (orb_refine_converged); the NDT pose it replaced
  // (valid when orb_refined), and the refinement's figures. Attempts (any hypothesis and the
  // polish), successes and the first failure's reason are counted for diagnosis.
  bool orb_refined = false;
  bool orb_refined_weak = false;
  Eigen::Isometry3d T_prior_world_ndt = Eigen::Isometry3d::Identity();
  int orb_refine_attempts = 0, orb_refine_accepted = 0;
  int orb_refine_inliers = 0;  // of the best fit's refinement
  double orb_refine_sigma_m = 0, orb_refine_sigma_rad = 0;
  std::string orb_refine_failure;  // the first failed attempt's (the best coarse fit is refined first)
  // An accepted converged fit whose ORB polish was tried and refused (too few inliers, gates): its
  // accuracy rests on NDT alone (relocalization_confirmation.hpp holds such a fit for confirmation).
  bool polish_refused = false;
  double wall_s = 0;
  // Where the time went: a + b (sampling, votes), c (matching, RANSAC, seeds), d + e (prior points,
  // NDT, acceptance); index_s: building the prior's LSH index (first call with a prior map, part of
  // appearance_s).
  double appearance_s = 0, geometry_s = 0, ndt_s = 0, index_s = 0;
  // ndt_s split by step (each 0 when the attempt ended before it): the coarse NDT of every
  // hypothesis, the fine NDT of the keep_best with step d', step e's checks up to the ORB
  // verification, its rivals (180 deg turn, second vote cluster, ORB rivals), the structure margin,
  // and the polish of an accepted converged fit.
  double coarse_s = 0, fine_s = 0, verify_s = 0, rivals_s = 0, margin_s = 0, polish_s = 0;
};

class Relocalizer {
 public:
  // max_features: the most features a query keyframe has (a query with more is refused), and the
  // most of a prior keyframe's matched with it (beyond: ignored; PriorMap::max_keyframe_features()).
  // Errors (kInvalidArgument): invalid intrinsics, max_features < 1, a config value out of range.
  static core::Expected<Relocalizer> create(const RelocalizerConfig& config, const hal::PinholeIntrinsics& K,
                                            int max_features);

  // One attempt (steps a-e above). Never returns an uncertain pose: localized is false unless
  // every acceptance test passed.
  RelocalizationResult relocalize(const RelocalizationQuery& query, PriorMap* prior);
  // Builds the LSH index over every prior keyframe's descriptors (step b). relocalize() calls it
  // when given a prior map other than the one indexed (PriorMap::instance_id()); calling
  // it after PriorMap::open keeps that time out of the first attempt (10-30 ms for the lab's 158k
  // prior features; FLANN's index took 0.2-0.4 s). Allocates (see Memory above).
  void prepare(const PriorMap& prior);
  // Builds the whole prior's NDT targets (RelocalizerConfig::whole_prior_targets) at every resolution
  // steps d and e use, over the clouds in memory, when all of them are (PriorMap::all_clouds_in_memory:
  // call it after PriorMap::preload_clouds); else, or when the config says no, leaves the per-query
  // targets in use. They serve relocalize() while the prior's clouds stay as they were
  // (PriorMap::cloud_generation). Allocates ~200-240 bytes per voxel of capacity (at most twice the
  // occupied voxels, within max_whole_prior_voxels; outdoor sim prior, 3.6M points: see
  // docs/relocalization.md). Nothing throws: a prior over the voxel budget or an allocation that fails
  // leaves nothing built and the per-query targets in use; the result says what was built or why not.
  struct WholePriorTargets {
    bool built = false;
    std::string why_not;          // when not built
    int64_t points = 0;           // prior points voxelised
    int levels = 0;               // resolutions built
    int64_t voxels = 0;           // occupied voxels, all levels
    int64_t capacity_voxels = 0;  // allocated (RelocalizerConfig::max_whole_prior_voxels bounds it)
    double seconds = 0;
  };
  // keep_going (optional) is asked before each resolution: false stops there, nothing built.
  WholePriorTargets prepare_targets(const PriorMap& prior, const std::function<bool()>& keep_going = {});

  const RelocalizerConfig& config() const;
  Relocalizer(Relocalizer&&) noexcept;
  Relocalizer& operator=(Relocalizer&&) noexcept;
  ~Relocalizer();

 private:
  struct Impl;
  explicit Relocalizer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hwr::recon
