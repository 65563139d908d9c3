// ism-train: CAD meshes -> virtual scans -> trained ISM model file.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>

#include "core/common/cli_checks.h"
#include "core/common/error.h"
#include "core/model/model_file.h"
#include "core/training/calibration.h"
#include "core/training/trainer.h"

namespace {

// The preset is the base the other options change, so it is read before them.
std::string presetOf(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--preset" && i + 1 < argc) return argv[i + 1];
    if (arg.rfind("--preset=", 0) == 0) return arg.substr(9);
  }
  return "default";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Train furniture Implicit Shape Models from CAD meshes rendered as virtual Kinect scans."};
  std::string folders, manifest, output, codebook = "both";
  std::string preset = presetOf(argc, argv);
  ism::TrainingParams params = preset == "seed" ? ism::seedTrainingParams() : ism::TrainingParams{};
  app.add_option("--preset", preset,
                 "default: the project's pipeline (gravity, upright votes, floors in the scans); seed: the 2012 "
                 "thesis's pipeline")
      ->check(CLI::IsMember({"default", "seed"}))
      ->capture_default_str();
  std::vector<std::string> bins;
  auto* folders_opt = app.add_option("--folders", folders, "ROOT with one folder of meshes per category");
  auto* manifest_opt = app.add_option("--manifest", manifest, "TSV: category path [width_m depth_m height_m up rotation credit]; category background: "
                                      "meshes that weigh the codewords against what is not furniture");
  folders_opt->excludes(manifest_opt);
  app.add_option("-o,--output", output, "model file to write")->required();
  std::string samples_path;
  app.add_option("--calibration-samples", samples_path,
                 "also write the calibration rooms' labelled peaks as TSV (one row per peak, every draw's; "
                 "tests/eval/domain_gap.py reads it)");
  app.add_option("--codebook", codebook, "global, separated or both")->check(CLI::IsMember({"global", "separated", "both"}));
  app.add_option("--k-global", params.global_kmeans.k, "codewords of the global codebook")->check(ism::cli::positive());
  std::string codebook_sampling = params.balanced_global_codebook ? "balanced" : "pooled";
  app.add_option("--codebook-sampling", codebook_sampling,
                 "the descriptors the global codebook's k-means clusters: balanced, as many of each category's "
                 "(the default preset), or pooled, a sample of all (the seed's)")
      ->check(CLI::IsMember({"pooled", "balanced"}));
  app.add_option("--k-separated", params.separated_kmeans.k, "codewords per category codebook")->check(ism::cli::positive());
  app.add_option("--activation-k", params.knn.k,
                 "codewords each descriptor activates (k-NN activation), with which thresholds and calibration are made")
      ->check(CLI::Range(1, 32));
  app.add_option("--views", params.views.views, "virtual scans per mesh")->check(ism::cli::positive());
  app.add_option("--view-distance", params.views.min_distance,
                 "training cameras at least this far from the object (m); 0 = as near as it fits in view")
      ->check(CLI::Range(0.0f, 20.0f));
  app.add_flag("--fused-scans", params.fused.enabled,
               "also each mesh's views fused into one map without image grid, as mapping stacks and ScanNet show "
               "furniture");
  app.add_option("--fused-spacing", params.fused.spacing, "a fused scan's points averaged per cube of this edge (m)")
      ->check(CLI::Range(0.005f, 0.2f));
  bool seed_front_end = false;
  auto* seed_front_end_opt = app.add_flag("--seed-front-end", seed_front_end,
               "the seed's scales (1 cm voxels, 3 cm normals, 8 cm SHOT) instead of the default 3 / 7.5 / 18 cm");
  app.add_option("--leaf-size", params.front_end.downsample.leaf_size, "downsampling voxel edge (m)")
      ->check(CLI::Range(0.002, 0.2))
      ->excludes(seed_front_end_opt);
  app.add_option("--normal-radius", params.front_end.normals.radius, "normal estimation radius (m)")
      ->check(CLI::Range(0.005, 0.5))
      ->excludes(seed_front_end_opt);
  app.add_option("--shot-radius", params.front_end.shot.radius, "SHOT descriptor support radius (m)")
      ->check(CLI::Range(0.02, 0.5))
      ->excludes(seed_front_end_opt);
  app.add_option("--surface-keypoints", params.front_end.keypoints.surface_spacing,
                 "besides the contours, one keypoint per cube of this edge on the surface off the floor and walls "
                 "(m; 0 = contours only, as the seed)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--wall-cell", params.front_end.gravity.wall_cell,
                 "walls as connected surfaces of cells of this size (m; 0 = every point on a wall's plane within "
                 "its extent, the default)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--wall-seen-through", params.front_end.gravity.wall_max_seen_through,
                 "a plane with more points seen through it than this fraction of its own is no wall (0 = not looked at; maps are not)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--given-up-kept", params.front_end.gravity.given_up_kept_deg,
                 "a scene's given up farther than this (deg) from the normal of a floor that holds more points than "
                 "the plane square to it gives way to that normal (10 or more: never)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 90.0));
  app.add_option("--threads", params.threads, "worker threads (0 = all cores)")->check(ism::cli::nonNegative());
  app.add_option("--bin", bins, "Hough bin size of a category, CATEGORY=METRES (repeatable)");
  // Each step of the default pipeline can be turned off alone: docs/EVALUATION.md's ablation.
  bool no_gravity = false, no_training_floor = false, no_calibration = false, no_shapes = false, no_shadow = false;
  std::string vote_frame, cloud_keypoints;
  app.add_option("--cloud-keypoints", cloud_keypoints,
                 "keypoints of unorganized clouds: range-image (contours seen from the sensor, the default) or boundary "
                 "(the seed's)")
      ->check(CLI::IsMember({"range-image", "boundary"}));
  app.add_flag("--no-gravity", no_gravity, "no up, floor or walls: keypoints anywhere, votes in the LRF, no heights");
  app.add_option("--vote-frame", vote_frame, "lrf (the seed's) or upright (the default)")
      ->check(CLI::IsMember({"lrf", "upright"}));
  app.add_option("--height-tolerance", params.voting.height_tolerance,
                 "cast only the votes of training keypoints within this height of the keypoint's (m); 0 = off")
      ->check(ism::cli::nonNegative());
  app.add_option("--height-weighting", params.voting.height_normalized,
                 "the height test's weights: normalized (a keypoint's weight spreads over the votes at its height, the "
                 "default) or lost (over all of its codeword's votes, so that those at other heights are lost)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, bool>{{"normalized", true}, {"lost", false}}));
  app.add_flag("--no-training-floor", no_training_floor, "render the training meshes without a floor");
  app.add_flag("--no-calibration", no_calibration, "no confidence calibration on rendered rooms");
  bool no_cloud_calibration = false;
  app.add_flag("--no-cloud-calibration", no_cloud_calibration,
               "calibrate on the rendered frames only, not also on them as unorganized point samples");
  app.add_flag("--calibration-maps", params.calibration.maps,
               "the clouds' calibration also learns from each rendered room seen as a map (fused, without pose), as "
               "room scans are sent: a better ranking on the dev clouds, fewer chairs at 0.5 (docs/EVALUATION.md)");
  app.add_flag("--no-verification", no_shapes,
               "keep no training shapes, so that recognition does not verify hypotheses against the scene's depth");
  bool no_calibration_checks = false;
  app.add_flag("--no-calibration-scene-checks", no_calibration_checks,
               "calibrate on every verified peak of the rendered rooms, not only on those that pass recognition's "
               "checks of the scene around them (scene_checks.h)");
  app.add_flag("--learned-weights", params.calibration.learned_weights.enabled,
               "lower the codeword weights of what the rendered rooms' false peaks are made of, learned before the "
               "confidence (discriminative_weights.h), as the shipped model is trained: more true chairs at the "
               "default operating point on the dev scans, tables and sofas ranked a little worse below it; "
               "training takes about twice as long (docs/EVALUATION.md)");
  bool bin_peaks = false;
  app.add_flag("--bin-peaks", bin_peaks,
               "centre the rendered rooms' peaks on their own bin's votes, as the seed, not on their bin's and its 26 "
               "neighbours': for recognition with --bin-peaks (hough_space.h)");
  bool kind_negatives = false;
  app.add_flag("--calibration-kind-negatives", kind_negatives,
               "count a rendered room's peak on an object of another category of its kind (a dining chair's on an "
               "office chair) against its category, not leave it out of the calibration");
  app.add_flag("--calibration-pooling", params.calibration.pooled,
               "fit each category's confidence with its slopes drawn towards those all categories share, not alone "
               "(for categories with few training meshes)");
  app.add_option("--calibration-pooling-spreads", params.calibration.pooling_spreads,
                 "with --calibration-pooling: the spreads of each category's slopes around the shared ones that the "
                 "calibration chooses among by leaving one fold of rooms out (0 = each category alone)")
      ->check(CLI::Range(0.0, 100.0));
  bool no_shape_profile = false;
  app.add_flag("--no-shape-profile", no_shape_profile,
               "calibrate confidence on the verification's fit alone, not also on how the measured surface's "
               "profile over height matches the training shapes'");
  app.add_flag("--no-projector-shadow", no_shadow,
               "render training scans and calibration rooms without the structured-light projector's shadow");
  app.add_option("--pixel-shift", params.noise.pixel_shift,
                 "training and calibration renders: each pixel reads the depth this many pixels off (Gaussian sigma; 0 = off)")
      ->check(CLI::Range(0.0, 3.0));
  app.add_option("--correlation-window", params.noise.window,
                 "training and calibration renders: drop pixels whose window (N x N) of the Kinect's dot pattern straddles "
                 "depths (0 = off)")
      ->check(CLI::Range(0, 21));
  app.add_option("--calibration-rooms", params.calibration.rooms_per_fold, "rendered rooms per calibration fold")
      ->check(ism::cli::positive());
  app.add_option("--calibration-background", params.calibration.background_objects,
                 "background meshes of the manifest placed in each calibration room (0 to this many)")
      ->check(ism::cli::nonNegative());
  app.add_option("--calibration-objects", params.calibration.max_objects,
                 "held-out furniture placed in each calibration room (1 to this many)")
      ->check(ism::cli::positive());
  app.add_option("--grouped-rooms", params.calibration.grouped_rooms,
                 "share of the calibration rooms that show a table with other furniture pulled up to it "
                 "(0 = every room stands its furniture apart)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--grouped-objects", params.calibration.max_grouped,
                 "furniture pulled up to the table of a grouped calibration room (1 to this many)")
      ->check(ism::cli::positive())
      ->capture_default_str();
  const std::map<std::string, ism::FitTerms> fit_terms{
      {"both", ism::FitTerms::kBoth}, {"inliers", ism::FitTerms::kInliers}, {"free-space", ism::FitTerms::kFreeSpace}};
  app.add_option("--fit-terms", params.calibration.fit_terms,
                 "the terms of verification's fit the calibration rooms are verified with: both, inliers (no "
                 "free space) or free-space (no inliers); recognise with ism-eval --fit-terms the same "
                 "(verification.h, FitTerms)")
      ->transform(CLI::CheckedTransformer(fit_terms))
      ->default_str("both");
  std::optional<uint32_t> training_seed;
  app.add_option("--seed", training_seed,
                 "another draw of training's randomness (k-means, sensor noise, calibration rooms); models of "
                 "several seeds tell a method's effect from chance (tests/eval/seeds.sh)");
  int draws = 1;
  app.add_option("--draws", draws,
                 "train N times, the i-th time (from 0) with --seed S+i (S 0 without --seed; the first time with "
                 "the given seed or none) and the others with the global codebook alone, and write one file: "
                 "recognition with the global codebook answers with all N as an ensemble (recognizer.h); about N "
                 "times the training time")
      ->check(ism::cli::positive())
      ->default_val(1);
  app.add_flag("--unsized-by-height", params.unsized_by_height,
               "scale meshes without a size by their category's typical height alone, as the seed preset does, "
               "instead of fitting their box to its typical width, depth and height");
  bool no_scene_smoothing = false;
  app.add_flag("--no-scene-smoothing", no_scene_smoothing,
               "recognise scenes without MLS smoothing, as training scans are: faster, see docs/EVALUATION.md");
  try {
    app.parse(argc, argv);
    if (folders.empty() == manifest.empty()) throw CLI::ValidationError("give exactly one of --folders or --manifest");
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }
  if (seed_front_end) {
    const ism::FrontEndParams seed;
    params.front_end.downsample = seed.downsample;
    params.front_end.smoothing.radius = seed.smoothing.radius;
    params.front_end.normals = seed.normals;
    params.front_end.keypoints.radius = seed.keypoints.radius;
    params.front_end.shot = seed.shot;
  }
  if (no_scene_smoothing) params.front_end.smoothing.enabled = false;
  if (training_seed) ism::reseed(params, *training_seed);
  if (!vote_frame.empty()) params.voting.frame = vote_frame == "lrf" ? ism::VoteFrame::kLrf : ism::VoteFrame::kUpright;
  if (no_gravity) {
    params.front_end.gravity.enabled = false;
    params.voting = {ism::VoteFrame::kLrf, 0.0f};
  }
  if (!cloud_keypoints.empty()) {
    params.front_end.keypoints.unorganized =
        cloud_keypoints == "boundary" ? ism::KeypointMethod::kBoundary : ism::KeypointMethod::kRangeImage;
  }
  if (no_training_floor) params.render_floor = false;
  if (no_calibration) params.calibration.enabled = false;
  if (no_cloud_calibration) params.calibration.clouds = false;
  if (no_shapes) params.shape_spacing = 0;
  if (no_shape_profile) params.calibration.shape_profile = false;
  if (no_calibration_checks) params.calibration.scene_checks = false;
  if (kind_negatives) params.calibration.kinds = false;
  if (bin_peaks) params.calibration.peak_centre = ism::PeakCentre::kBin;
  if (no_shadow) params.noise.projector_shadow = false;
  if (params.voting.frame == ism::VoteFrame::kUpright && !params.front_end.gravity.enabled) {
    std::cerr << "ism-train: upright vote frames need the gravity stage (drop --no-gravity or use --vote-frame lrf)\n";
    return 2;
  }
  for (const auto& bin : bins) {
    const auto eq = bin.find('=');
    try {
      if (eq == std::string::npos || eq == 0) throw std::invalid_argument("no CATEGORY=");
      const float size = std::stof(bin.substr(eq + 1));
      if (!(size > 0)) throw std::invalid_argument("not positive");
      params.bin_sizes[bin.substr(0, eq)] = size;
    } catch (const std::exception&) {
      std::cerr << "ism-train: --bin '" << bin << "' must be CATEGORY=SIZE with SIZE > 0 in metres\n";
      return 2;
    }
  }
  params.balanced_global_codebook = codebook_sampling == "balanced";
  params.global_codebook = codebook != "separated";
  if (draws > 1 && !params.global_codebook) {
    std::cerr << "ism-train: --draws needs the global codebook (an ensemble answers with it): drop --codebook separated\n";
    return 2;
  }
  params.separated_codebooks = codebook != "global";
  for (int i = 0; i < argc; ++i) params.command += (i ? " " : "") + std::string(argv[i]);
  params.progress = [](const std::string& line) { std::cout << line << std::endl; };
  std::ofstream samples_file;
  int draw = 0;
  if (!samples_path.empty()) {
    samples_file.open(samples_path);
    if (!samples_file) {
      std::cerr << "ism-train: --calibration-samples: cannot write " << samples_path << '\n';
      return 2;
    }
    samples_file << "draw\tcategory\tpositive\tscore\tsupport\tfit\tprofile_distance\tcloud\tfold\tconfidence\n";
    params.calibration_samples = [&](const ism::Model& model, const std::vector<ism::CalibrationSample>& samples) {
      for (const auto& x : samples) {
        const ism::CategoryModel& category = model.categories[static_cast<size_t>(x.category)];
        // The confidence its category's curve gives it; empty where the category has none.
        const auto& curve = x.cloud ? category.cloud_calibration : category.calibration;
        samples_file << draw << '\t' << category.name << '\t' << x.positive << '\t' << x.score << '\t' << x.support
                     << '\t' << x.fit << '\t' << x.profile_distance << '\t' << x.cloud << '\t' << x.fold << '\t';
        if (curve) samples_file << curve->confidence(x.score, x.support, x.fit, x.profile_distance);
        samples_file << '\n';
      }
      ++draw;
    };
  }
  try {
    const auto meshes = folders.empty() ? ism::readManifest(manifest) : ism::meshesFromFolders(folders);
    for (const auto& m : meshes) params.bin_sizes.emplace(m.category, ism::defaultBinSize(m.category));
    std::cout << "training on " << meshes.size() << " meshes, " << params.views.views << " views each" << std::endl;
    ism::Model model = ism::train(meshes, params);
    for (int d = 1; d < draws; ++d) {
      std::cout << "draw " << d + 1 << " of " << draws << ": --seed " << training_seed.value_or(0) + d << std::endl;
      ism::TrainingParams again = params;
      ism::reseed(again, training_seed.value_or(0) + static_cast<uint32_t>(d));
      again.separated_codebooks = false;  // the ensemble answers with the global codebook
      again.global_codebook = true;
      model.draws.push_back(ism::train(meshes, again));
    }
    ism::saveModel(model, output);
    if (samples_file.is_open() && !samples_file.flush()) {
      std::cerr << "ism-train: --calibration-samples: writing " << samples_path << " failed\n";
      return 1;
    }
    std::cout << "wrote " << output << " (" << model.categories.size() << " categories)" << std::endl;
  } catch (const ism::Error& e) {
    std::cerr << "ism-train: " << ism::errorCodeName(e.code()) << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}
