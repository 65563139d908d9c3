// ism-detect: recognise furniture in point clouds (PCD/PLY) or depth PNGs with a trained model.
#include <CLI/CLI.hpp>
#include <optional>
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "core/common/cli_checks.h"
#include "core/common/error.h"
#include "core/io/cloud_io.h"
#include "core/model/model_file.h"
#include "core/recognition/recognizer.h"
#include "core/report/report.h"
#include "core/tools/scene_check_flags.h"

namespace {

bool isPng(std::string path) {
  std::transform(path.begin(), path.end(), path.begin(), [](unsigned char c) { return std::tolower(c); });
  return path.size() > 4 && path.compare(path.size() - 4, 4, ".png") == 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Recognise furniture in scenes with a trained ISM model."};
  std::vector<std::string> model_paths;
  std::string codebook = "global", activation = "knn", weighting = "lw", categories, picture, debug_ply;
  std::vector<std::string> files;
  ism::DepthIntrinsics intrinsics;
  ism::RecognitionOptions options;
  float min_score = 0;
  bool json = false, no_box_selection = false;
  std::string preset = "default", up;
  app.add_option("-m,--model", model_paths,
                 "trained model file; given again, an ensemble: models of the same categories and front end, trained "
                 "with other --seed, their answers averaged (default preset)")
      ->required()
      ->allow_extra_args(false);
  app.add_option("files", files, "scenes: .pcd, .ply, or 16-bit depth .png")->required();
  app.add_option("--fx", intrinsics.fx, "depth PNG focal length x (px)");
  app.add_option("--fy", intrinsics.fy, "depth PNG focal length y (px)");
  app.add_option("--cx", intrinsics.cx, "depth PNG principal point x (px)");
  app.add_option("--cy", intrinsics.cy, "depth PNG principal point y (px)");
  app.add_option("--depth-scale", intrinsics.depth_scale, "depth PNG units per metre")->check(ism::cli::positive());
  app.add_option("--codebook", codebook, "global or separated")->check(CLI::IsMember({"global", "separated"}));
  app.add_option("--activation", activation, "knn or cutoff")->check(CLI::IsMember({"knn", "cutoff"}));
  app.add_option("--k", options.strategy.activation.k, "codewords per descriptor (knn)")->check(ism::cli::positive());
  app.add_option("--cutoff", options.strategy.activation.cutoff, "activation distance (cutoff)")->check(ism::cli::positive());
  app.add_option("--weighting", weighting, "vote weights: cw, lw or aw")->check(CLI::IsMember({"cw", "lw", "aw"}));
  app.add_option("--categories", categories, "comma-separated categories (default: all)");
  auto* min_score_opt = app.add_option("--min-score", min_score, "score threshold instead of the model's");
  app.add_option("--preset", preset, "default (confidence, upright boxes, one answer per object) or seed")
      ->check(CLI::IsMember({"default", "seed"}))
      ->capture_default_str();
  app.add_option("--min-confidence", options.min_confidence, "default preset: drop hypotheses below this")
      ->check(CLI::Range(0.0f, 0.99f))
      ->capture_default_str();
  app.add_option("--up", up, "the scene's up direction, X,Y,Z in its coordinates, when known (else the floor is found)");
  bool trust_given_up = false;
  app.add_flag("--trust-given-up", trust_given_up,
               "keep --up even where the scene's floor is tilted from it (GravityParams::given_up_kept_deg)");
  app.add_option("--max", options.max_hypotheses, "at most N hypotheses (0 = all)")->check(ism::cli::nonNegative());
  app.add_flag("--json", json, "print JSON instead of a table");
  app.add_option("--picture", picture,
                 "write the scene as PNG with the boxes and the training shapes verification fitted drawn (one input only)");
  app.add_option("--debug-ply", debug_ply, "write keypoints, votes and centres as PLY (one input only)");
  app.add_flag("--keypoints", options.return_keypoints,
               "with --json, each hypothesis' supporting keypoints (support_keypoints), as ism-client's --keypoints");
  app.add_flag("--no-box-selection", no_box_selection, "keep hypotheses whose box fails the learned limits");
  bool no_verify = false;
  app.add_flag("--no-verify", no_verify, "default preset: leave the hypotheses unverified against the scene");
  bool bin_peaks = false;
  app.add_flag("--bin-peaks", bin_peaks, ism::cli::kBinPeaksHelp);
  app.add_option("--icp", options.verification.icp_iterations,
                 "default preset: steps of ICP (a turn about up and a shift along the floor) after verification's pose "
                 "search; 0 keeps the search's pose")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  ism::cli::SceneCheckFlags scene_check_flags;
  scene_check_flags.add(app);
  try {
    app.parse(argc, argv);
    if (files.size() > 1 && (!picture.empty() || !debug_ply.empty())) {
      throw CLI::ValidationError("--picture and --debug-ply take a single input file");
    }
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }
  try {
    options.strategy.codebook = ism::parseCodebookType(codebook);
    options.strategy.activation.strategy = ism::parseActivationStrategy(activation);
    options.strategy.weighting = ism::parseVoteWeighting(weighting);
    std::stringstream list(categories);
    for (std::string c; std::getline(list, c, ',');) {
      if (!c.empty()) options.categories.push_back(c);
    }
    if (*min_score_opt) options.min_score = min_score;
    options.preset = ism::parseRecognitionPreset(preset);
    std::optional<Eigen::Vector3f> given_up;
    if (!up.empty()) {
      std::stringstream text(up);
      Eigen::Vector3f v;
      char comma1 = 0, comma2 = 0;
      if (!(text >> v.x() >> comma1 >> v.y() >> comma2 >> v.z()) || comma1 != ',' || comma2 != ',' || !v.allFinite() ||
          !(v.norm() > 0)) {
        throw ism::Error(ism::ErrorCode::kInvalidInput, "--up '" + up + "' is not three numbers X,Y,Z of a non-zero vector");
      }
      given_up = v;
    }
    options.box_selection = !no_box_selection;
    options.verify = !no_verify;
    if (bin_peaks) options.peak_centre = ism::PeakCentre::kBin;
    scene_check_flags.apply(options.scene_checks);
    options.keep_votes = !debug_ply.empty();
    std::vector<ism::Model> loaded;
    for (const auto& path : model_paths) loaded.push_back(ism::loadModel(path));
    if (trust_given_up) {
      for (auto& m : loaded) m.trustGivenUp();
    }
    std::vector<const ism::Model*> models;
    for (const auto& m : loaded) models.push_back(&m);
    const ism::Model& model = loaded.front();  // the picture's and the votes' model

    nlohmann::json all = nlohmann::json::array();
    for (const auto& file : files) {
      ism::Scene scene = isPng(file) ? ism::loadDepthPng(file, intrinsics) : ism::loadCloudFile(file);
      scene.up = given_up;
      const ism::RecognitionResult result = ism::recognizeEnsemble(models, scene, options);
      if (json) {
        nlohmann::json j = ism::toJson(result);
        j["file"] = file;
        j["strategy"] = {{"codebook", codebook}, {"activation", activation}, {"weighting", weighting}};
        all.push_back(std::move(j));
      } else {
        std::cout << "== " << file << ": " << result.input_points << " points, " << result.keypoints << " keypoints\n"
                  << ism::hypothesesTable(result, no_box_selection) << "timings (ms):";
        for (const auto& [stage, ms] : result.timings.stages) std::printf(" %s %.1f", stage.c_str(), ms);
        std::printf(", total %.1f\n", result.timings.total());
      }
      if (!picture.empty()) {
        ism::PictureParams pp;
        if (isPng(file)) {
          static_cast<ism::PinholeIntrinsics&>(pp) = intrinsics;
        }
        if (scene.image_width > 0) pp.width = scene.image_width, pp.height = scene.image_height;
        if (result.gravity) pp.up = result.gravity->up;
        ism::savePicture(scene, result.hypotheses, picture, pp, &model);
      }
      if (!debug_ply.empty()) ism::saveDebugPly(model, result, debug_ply);
    }
    if (json) std::cout << all.dump(2) << std::endl;
  } catch (const ism::Error& e) {
    std::cerr << "ism-detect: " << ism::errorCodeName(e.code()) << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}
