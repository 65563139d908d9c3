// ism-eval: the seed's evaluation. `baseline` trains on synthetic scans of some meshes and tests
// on scans of others; `real` scores a trained model on real scenes with ground truth.
#include <CLI/CLI.hpp>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>

#include "core/common/cli_checks.h"
#include "core/common/error.h"
#include "core/eval/eval.h"
#include "core/model/model_file.h"
#include "core/tools/scene_check_flags.h"

namespace {

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text << "\n";
  if (!out) throw ism::Error(ism::ErrorCode::kIo, "cannot write " + path);
}

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
  if (!out) throw ism::Error(ism::ErrorCode::kIo, "cannot write " + path);
}

void progress(const std::string& line) { std::cerr << line << std::endl; }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Evaluate furniture recognition as the seed did: synthetic baseline or real scenes"};
  app.require_subcommand(1);
  std::string json_path;

  CLI::App* baseline = app.add_subcommand("baseline", "train on synthetic scans of N meshes per category, "
                                                      "test on scans of M others, all six seed combinations");
  std::string manifest, folders, train_list, test_list;
  int train_per_category = 3, test_per_category = 2;
  // The preset is the base the training options change, so it is read before them.
  bool seed_preset = false;
  for (int i = 1; i + 1 < argc; ++i) seed_preset |= std::string(argv[i]) == "--preset" && std::string(argv[i + 1]) == "seed";
  for (int i = 1; i < argc; ++i) seed_preset |= std::string(argv[i]) == "--preset=seed";
  ism::TrainingParams training = seed_preset ? ism::seedTrainingParams() : ism::TrainingParams{};
  training.command = "ism-eval baseline";
  auto* manifest_opt = baseline->add_option("--manifest", manifest, "TSV: category path [width depth height up ...]")
                           ->check(CLI::ExistingFile);
  auto* folders_opt = baseline->add_option("--folders", folders, "ROOT/<category>/*.{obj,off,ply}")
                          ->check(CLI::ExistingDirectory);
  auto* train_list_opt = baseline->add_option("--train-list", train_list, "manifest of the training meshes")
                             ->check(CLI::ExistingFile);
  auto* test_list_opt = baseline->add_option("--test-list", test_list, "manifest of the test meshes")
                            ->check(CLI::ExistingFile);
  manifest_opt->excludes(folders_opt);
  train_list_opt->needs(test_list_opt)->excludes(manifest_opt)->excludes(folders_opt);
  test_list_opt->needs(train_list_opt);
  baseline->add_option("--train", train_per_category, "training meshes per category (first by path)")
      ->capture_default_str()->check(ism::cli::positive());
  baseline->add_option("--test", test_per_category, "test meshes per category (the next ones by path)")
      ->capture_default_str()->check(ism::cli::positive());
  baseline->add_option("--views", training.views.views, "virtual scans per mesh")
      ->capture_default_str()->check(ism::cli::positive());
  baseline->add_option("--k-global", training.global_kmeans.k, "global codebook size")
      ->capture_default_str()->check(ism::cli::positive());
  baseline->add_option("--k-separated", training.separated_kmeans.k, "per-category codebook size")
      ->capture_default_str()->check(ism::cli::positive());
  baseline->add_option("--threads", training.threads, "0 = all cores")->capture_default_str();
  baseline->add_option("--json", json_path, "also write the results as JSON");
  std::optional<uint32_t> training_seed;
  baseline->add_option("--seed", training_seed, "another draw of training's randomness, as ism-train --seed");
  baseline->add_flag("--unsized-by-height", training.unsized_by_height,
                     "scale meshes without a size by their category's typical height alone (the seed preset's rule)");

  CLI::App* real = app.add_subcommand("real", "score a model on real scenes (NAME.pcd + NAME.json)");
  std::vector<std::string> model_paths;
  std::string codebook = "global", activation = "knn", weighting = "lw", viewpoint = "auto";
  std::vector<std::string> inputs, mappings;
  bool all_combinations = false;
  float eye_height = 1.5f;
  real->add_option("-m,--model", model_paths,
                   "trained model; given again, an ensemble of models of the same categories and front end (ensemble.h)")
      ->required()
      ->allow_extra_args(false)
      ->check(CLI::ExistingFile);
  real->add_option("scenes", inputs, "folders of scenes, .json or .pcd files")->required();
  real->add_option("--codebook", codebook, "global | separated")->capture_default_str();
  real->add_option("--activation", activation, "knn | cutoff")->capture_default_str();
  real->add_option("--weighting", weighting, "cw | lw | aw")->capture_default_str();
  real->add_flag("--all-combinations", all_combinations, "the seed's six combinations instead of one");
  real->add_option("--map", mappings,
                   "model=gt1|gt2 (repeatable) replaces the default mapping of one model category; defaults: "
                   "office_chair,dining_chair=chair dining_table=table|desk couch=sofa");
  real->add_option("--viewpoint", viewpoint,
                   "auto | origin | room-centre: where normals point (auto: as recognition decides, the file's "
                   "pose, else the origin of a single view, else a map's middle at --eye-height above its floor)")
      ->capture_default_str();
  real->add_option("--eye-height", eye_height, "room-centre viewpoint height above the floor (m)")
      ->capture_default_str();
  real->add_option("--json", json_path, "also write the results as JSON");
  bool no_up = false;
  real->add_flag("--no-up", no_up, "never pass the scenes' up, as a caller who does not know it");
  std::vector<float> up_tilt;
  real->add_option("--up-tilt", up_tilt,
                   "DEG,AZIMUTH: turn each given up by DEG towards AZIMUTH (deg from the scene's x to its y), "
                   "to measure how the answers move with it (tests/eval/tilt_spread.py)")
      ->delimiter(',')
      ->expected(2)
      ->check(CLI::Range(-360.0f, 360.0f));
  bool trust_given_up = false;
  real->add_flag("--trust-given-up", trust_given_up,
                 "keep the scenes' up even where their floor is tilted from it (GravityParams::given_up_kept_deg)");
  bool no_verify = false;
  real->add_flag("--no-verify", no_verify, "default preset: leave the hypotheses unverified (verification.h)");
  bool centre_suppression = false;
  real->add_flag("--centre-suppression", centre_suppression,
                 "default preset: across categories, a centre in the other's footprint makes one object whatever "
                 "surface each explains (suppression.h)");
  bool own_peak_support = false;
  real->add_flag("--own-peak-support", own_peak_support,
                 "default preset: an answer's supporting keypoints (the seed's centre rule reads their centroid) are "
                 "its own peak's, not also those of the peaks of its category it merged, nor a table's those voting "
                 "at its box's centre (suppression.h)");
  bool merged_top_support = false;
  real->add_flag("--merged-top-support", merged_top_support,
                 "default preset: a table's supporting keypoints are those of the peaks it merged and of the weak "
                 "peaks its box holds, not those with a vote in the bin at its box's centre (suppression.h)");
  std::string map_verification = "3d";
  real->add_option("--map-verification", map_verification,
                   "default preset: how maps (clouds around their viewpoint) are verified: 3d, each shape point "
                   "against the measured points near it, or viewpoint, on a depth buffer from the made-up viewpoint "
                   "(verification.h)")
      ->check(CLI::IsMember({"3d", "viewpoint"}))
      ->capture_default_str();
  int icp_iterations = 0;
  real->add_option("--icp", icp_iterations,
                   "default preset: steps of ICP (a turn about up and a shift along the floor) after verification's "
                   "pose search; 0 keeps the search's pose (verification.h)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  ism::FitTerms fit_terms = ism::FitTerms::kBoth;
  const std::map<std::string, ism::FitTerms> fit_term_names{
      {"both", ism::FitTerms::kBoth}, {"inliers", ism::FitTerms::kInliers}, {"free-space", ism::FitTerms::kFreeSpace}};
  real->add_option("--fit-terms", fit_terms,
                   "default preset: the terms of verification's fit, both, inliers (no free space) or free-space (no "
                   "inliers), as the model was trained with (ism-train --fit-terms; verification.h)")
      ->transform(CLI::CheckedTransformer(fit_term_names))
      ->default_str("both");
  ism::cli::SceneCheckFlags scene_check_flags;
  for (CLI::App* sub : {baseline, real}) scene_check_flags.add(*sub);
  std::string preset = "default";
  float min_confidence = ism::RecognitionOptions{}.min_confidence;
  bool bin_peaks = false;
  for (CLI::App* sub : {baseline, real}) {
    sub->add_flag("--bin-peaks", bin_peaks, ism::cli::kBinPeaksHelp);
    sub->add_option("--preset", preset, "default | seed: the recognition pipeline evaluated")
        ->check(CLI::IsMember({"default", "seed"}))
        ->capture_default_str();
    sub->add_option("--min-confidence", min_confidence,
                    "default preset: the operating point r, TP and FP are counted at (AP ranks everything)")
        ->check(CLI::Range(0.0f, 0.99f))
        ->capture_default_str();
  }
  std::string pr_curve;
  real->add_option("--pr-curve", pr_curve,
                   "write the precision-recall curves (3D IoU 0.25) as PNG; with several combinations, "
                   "one file per combination with its number before the extension");

  CLI11_PARSE(app, argc, argv);

  // What is recognised and how, for either subcommand: the options only `real` offers keep their
  // defaults, which are EvalRecognition's, under `baseline`.
  ism::EvalRecognition recognition;
  try {
    recognition.preset = ism::parseRecognitionPreset(preset);
    recognition.min_confidence = min_confidence;
    recognition.verify = !no_verify;
    if (bin_peaks) recognition.peak_centre = ism::PeakCentre::kBin;
    recognition.shared_surface = !centre_suppression;
    recognition.maps_in_3d = map_verification == "3d";
    recognition.icp_iterations = icp_iterations;
    recognition.fit_terms = fit_terms;
    recognition.merge_support = !own_peak_support;
    recognition.top_support = !own_peak_support && !merged_top_support;
    scene_check_flags.apply(recognition.scene_checks);
    std::string text, json;
    if (baseline->parsed()) {
      if (manifest.empty() && folders.empty() && train_list.empty()) {
        throw ism::Error(ism::ErrorCode::kInvalidInput, "baseline needs --manifest, --folders or --train-list/--test-list");
      }
      ism::MeshSplit split;
      if (!train_list.empty()) {
        split = {ism::readManifest(train_list), ism::readManifest(test_list)};
      } else {
        auto meshes = manifest.empty() ? ism::meshesFromFolders(folders) : ism::readManifest(manifest);
        split = ism::splitMeshes(meshes, train_per_category, test_per_category);
      }
      training.progress = progress;
      if (training_seed) ism::reseed(training, *training_seed);
      auto result = ism::runBaseline(split, training, recognition);
      text = ism::formatBaseline(result);
      json = ism::baselineToJson(result);
    } else {
      ism::RealEvalParams params;
      params.recognition = recognition;
      for (const auto& spec : mappings) ism::addCategoryMapping(params.mapping, spec);
      params.viewpoint = ism::parseViewpointPolicy(viewpoint);
      params.eye_height = eye_height;
      params.give_up = !no_up;
      if (!up_tilt.empty()) {
        params.up_tilt_deg = up_tilt[0];
        params.up_tilt_azimuth_deg = up_tilt[1];
      }
      params.progress = progress;
      // Every annotation is checked before the long run starts.
      std::vector<ism::AnnotatedScene> scenes;
      for (const auto& path : ism::findSceneAnnotations(inputs)) scenes.push_back(ism::readSceneAnnotation(path));
      std::vector<ism::Model> loaded;
      for (const auto& path : model_paths) loaded.push_back(ism::loadModel(path));
      if (trust_given_up) {
        for (auto& m : loaded) m.trustGivenUp();
      }
      const ism::Model& model = loaded.front();
      for (size_t m = 1; m < loaded.size(); ++m) params.more_models.push_back(&loaded[m]);
      if (all_combinations) {
        params.strategies = ism::seedCombinations(model);
      } else {
        ism::Strategy strategy;
        strategy.codebook = ism::parseCodebookType(codebook);
        strategy.activation = ism::parseActivationStrategy(activation) == ism::ActivationStrategy::kKnn
                                  ? model.trained_knn
                                  : model.trained_cutoff;
        strategy.weighting = ism::parseVoteWeighting(weighting);
        params.strategies = {{ism::strategyName(strategy), strategy}};
      }
      auto result = ism::evaluateRealScenes(model, scenes, params);
      text = ism::formatReal(result);
      json = ism::realToJson(result);
      for (size_t c = 0; !pr_curve.empty() && c < result.combinations.size(); ++c) {
        std::string path = pr_curve;
        if (result.combinations.size() > 1) {
          const auto dot = path.rfind('.');
          path.insert(dot == std::string::npos ? path.size() : dot, "-" + std::to_string(c + 1));
        }
        writeBytes(path, ism::renderPrecisionRecall(result.combinations[c]));
      }
    }
    std::cout << text;
    if (!json_path.empty()) writeText(json_path, json);
  } catch (const ism::Error& e) {
    std::cerr << "ism-eval: " << ism::errorCodeName(e.code()) << ": " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
