// Unit tests of the CLI's job-file parser, output names and mesh checks (hdeform_cli_job).
#include "job_file.h"
#include "mesh_check.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

namespace fs = std::filesystem;
using namespace hdeform::cli;

namespace {

// The message parse_job throws for `text` ("" when it accepts it).
std::string error_of(const std::string& text) {
  try {
    parse_job(text, "job.json", "");
  } catch (const FileError& e) {
    return e.what();
  }
  return "";
}

const char* kMinimal = R"({"meshes": ["cactus"], "constraints": [{"handles": ["ids:1"]}]})";

std::string with(const std::string& extra) {
  return R"({"meshes": ["cactus"], "constraints": [{"handles": ["ids:1"]}], )" + extra + "}";
}

}  // namespace

TEST(FileNamePart, KeepsSafeNamesAndReplacesEverythingElse) {
  EXPECT_EQ(file_name_part("bend_1.5-x"), "bend_1.5-x");
  EXPECT_EQ(file_name_part("../../etc/x"), "___.._etc_x");  // one component: no traversal
  EXPECT_EQ(file_name_part("/abs"), "_abs");
  EXPECT_EQ(file_name_part("a/b"), "a_b");
  EXPECT_EQ(file_name_part(".."), "__");
  EXPECT_EQ(file_name_part("."), "_");
  EXPECT_EQ(file_name_part(".hidden"), "_hidden");
  EXPECT_EQ(file_name_part("-rf"), "_rf");
  EXPECT_EQ(file_name_part(std::string("a\0b", 3)), "a_b");
  EXPECT_EQ(file_name_part("c:\\win\\x"), "c__win_x");
  EXPECT_EQ(file_name_part("\x1b[31m"), "__31m");
  EXPECT_EQ(file_name_part("caf\xc3\xa9"), "caf__");
  EXPECT_EQ(file_name_part(""), "_");
  const std::string a(300, 'a'), b = std::string(299, 'a') + "b";
  EXPECT_EQ(file_name_part(a).size(), kMaxNamePart);
  EXPECT_NE(file_name_part(a), file_name_part(b));  // the hash keeps long names apart
  EXPECT_EQ(file_name_part(file_name_part(a)), file_name_part(a));
}

TEST(ParseJob, AcceptsTheExamplesAndSanitizesNames) {
  const Job job = parse_job(
      R"({"meshes": [{"name": "../../etc/x", "library": "cactus"}],
          "constraints": [{"name": "/abs", "handles": ["ids:1", "ids:2"]}],
          "transforms": [{"name": "a/b", "rotate": "x,30"},
                         {"name": "..", "handles": [{"scale": 2}, {"translate": [0, 0, 1]}]}]})",
      "job.json", "");
  ASSERT_EQ(job.transforms.size(), 2u);
  EXPECT_EQ(item_file_name(job, job.meshes[0], job.constraints[0], job.transforms[0], 0),
            "___.._etc_x-_abs-a_b-b0.glb");
  EXPECT_EQ(item_file_name(job, job.meshes[0], job.constraints[0], job.transforms[1], kAutoBeta),
            "___.._etc_x-_abs-__-bauto.glb");
  EXPECT_EQ(job.output_dir, "hdeform-out/job");
}

TEST(ParseJob, RejectsCollidingNamesNamingBoth) {
  const std::string e = error_of(
      R"({"meshes": ["cactus"], "constraints": [{"name": "a/b", "handles": ["ids:1"]},
                                               {"name": "a_b", "handles": ["ids:2"]}]})");
  EXPECT_NE(e.find("constraints[1]: name 'a_b' and constraints[0] name 'a/b'"), std::string::npos)
      << e;
  EXPECT_NE(error_of(with(R"("transforms": [{"name": "X"}, {"name": "x"}])"))
                .find("transforms[1]"), std::string::npos);
  // Dashes: "a-b" + "c" and "a" + "b-c" would write the same file.
  const std::string d = error_of(
      R"({"meshes": [{"name": "a-b", "library": "cactus"}, {"name": "a", "library": "cactus"}],
          "constraints": [{"name": "c", "handles": ["ids:1"]}, {"name": "b-c", "handles": ["ids:1"]}]})");
  EXPECT_NE(d.find("would both write 'a-b-c-rest-b0.glb'"), std::string::npos) << d;
  EXPECT_NE(error_of(with(R"("betas": [0.1, 0.1000000001])")).find("betas[1]: same as betas[0]"),
            std::string::npos);
}

TEST(ParseJob, KeepsSummaryAndOutputDirInside) {
  EXPECT_NE(error_of(with(R"("summary": "../x.csv")")).find("summary: '../x.csv' is not a plain file name"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"("summary": "/tmp/x.csv")")).find("summary:"), std::string::npos);
  EXPECT_NE(error_of(with(R"("summary": ".bashrc")")).find("summary:"), std::string::npos);
  EXPECT_NE(error_of(with(R"("output_dir": "/etc")")).find("output_dir: '/etc' is absolute"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"("output_dir": "out/../../x")")).find("output_dir:"), std::string::npos);
  EXPECT_EQ(error_of(with(R"("output_dir": "out/sub", "summary": "s.csv")")), "");
  EXPECT_EQ(parse_job(with(R"("name": "../../x")"), "j.json", "").output_dir, "hdeform-out/___.._x");
}

TEST(ParseJob, RejectsNonFiniteAndBadTransforms) {
  EXPECT_NE(error_of(with(R"("transforms": [{"translate": [1e400, 0, 0]}])")).find("number overflow"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"("transforms": [{"scale": "inf"}])"))
                .find("job.json: transforms[0] scale: 'inf' is not a finite number"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"("transforms": [{"translate": "1e999,0,0"}])")).find("not a finite number"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"("transforms": [{"rotate": "0,0,0,30"}])")).find("rotation axis is zero"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"("transforms": [{"translate": [0, 0]}])")).find("expected 3"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"("transforms": [{"handles": [{"scale": 2}, {"scale": 3}]}])"))
                .find("2 transforms for 1 handles of constraints 'c0'"),
            std::string::npos);
}

TEST(ParseJob, TypeErrorsNameTheField) {
  EXPECT_EQ(error_of(R"({"meshes": [1], "constraints": []})"), "job.json: meshes[0]: expected an object");
  EXPECT_EQ(error_of(R"({"meshes": ["cactus"], "constraints": [{"handles": ["ids:1"], "name": 3}]})"),
            "job.json: constraints[0].name: expected a string");
  EXPECT_EQ(error_of(with(R"("betas": [null])")), "job.json: betas[0]: expected a number or \"auto\"");
  EXPECT_EQ(error_of(with(R"("transforms": [{"scale": {}}])")),
            "job.json: transforms[0].scale: expected a string, a number or an array of numbers");
  EXPECT_EQ(error_of(with(R"("transforms": [{"pivot": [0, "a", 0]}])")),
            "job.json: transforms[0].pivot[1]: expected a number");
  EXPECT_EQ(error_of("[]"), "job.json: expected an object");
  EXPECT_EQ(error_of("{\n\"meshes\": [\n}"), error_of("{\n\"meshes\": [\n}"));
  EXPECT_EQ(error_of("{\n\"meshes\": [\n}").rfind("job.json:3: ", 0), 0u) << error_of("{\n\"meshes\": [\n}");
  EXPECT_NE(error_of(std::string(100, '[') + std::string(100, ']')).find("nested deeper than"),
            std::string::npos);
  EXPECT_NE(error_of("{\"meshes\": [\"\xff\"]}").find("job.json:1: "), std::string::npos);
  EXPECT_EQ(error_of(kMinimal), "");
}

TEST(ParseJob, AnimationKeysNameTransformsAndAreChecked) {
  const std::string transforms = R"("transforms": [{"name": "bend", "rotate": "x,30"}], )";
  auto anim = [&](const std::string& body) {
    return with(transforms + R"("animation": )" + body);
  };
  const Job job = parse_job(
      anim(R"({"name": "wave", "fps": 12, "easing": "smoothstep", "energies": true, "up": "z",
               "keys": [{"time": 0, "transform": "rest"}, {"time": 1.5, "transform": "bend",
                         "beta": 0.25}]})"),
      "job.json", "");
  ASSERT_TRUE(job.animation.present);
  EXPECT_EQ(job.animation.fps, 12);
  EXPECT_EQ(job.animation.easing, "smoothstep");
  EXPECT_TRUE(job.animation.energies);
  ASSERT_EQ(job.animation.keys.size(), 2u);
  EXPECT_EQ(job.animation.keys[0].transform_index, kRestTransform);
  EXPECT_EQ(job.animation.keys[1].transform_index, 0u);
  EXPECT_TRUE(job.animation.keys[1].has_beta);
  EXPECT_EQ(animation_file_name(job, job.meshes[0], job.constraints[0], 0),
            "cactus-c0-wave-b0.glb");
  EXPECT_FALSE(parse_job(kMinimal, "job.json", "").animation.present);

  EXPECT_EQ(error_of(anim(R"({"keys": [{"time": 2, "transform": "rest"},
                                        {"time": 1, "transform": "bend"}]})")),
            "job.json: animation.keys[1].time: 1 is not after the previous key's 2");
  EXPECT_EQ(error_of(anim(R"({"keys": [{"time": 0, "transform": "twist"}]})")),
            "job.json: animation.keys[0].transform: 'twist' is not the name of a \"transforms\" "
            "entry (or \"rest\")");
  EXPECT_NE(error_of(anim(R"({"fps": 500, "keys": [{"time": 0, "transform": "rest"}]})"))
                .find("animation.fps: 500 is not in (0, 120]"),
            std::string::npos);
  EXPECT_NE(error_of(anim(R"({"keys": [{"time": 0, "transform": "rest", "beta": 1}]})"))
                .find("animation.keys[0].beta"),
            std::string::npos);
  EXPECT_NE(error_of(anim(R"({"keys": []})")).find("animation.keys"), std::string::npos);
  EXPECT_NE(error_of(anim(R"({"keys": [{"time": 0}]})")).find("expected \"time\" and"),
            std::string::npos);
  EXPECT_NE(error_of(anim(R"({"up": "x", "keys": [{"time": 0, "transform": "rest"}]})"))
                .find("animation.up"),
            std::string::npos);
  EXPECT_NE(error_of(anim(R"({"loop": 1, "keys": [{"time": 0, "transform": "rest"}]})"))
                .find("unknown key"),
            std::string::npos);
  EXPECT_NE(error_of(with(transforms + R"("betas": ["auto"], "animation": {"keys": [{"time": 0,
                               "transform": "rest"}]})"))
                .find("cannot be animated"),
            std::string::npos);
  // The animation's files must not collide with the still items' files.
  EXPECT_NE(error_of(anim(R"({"name": "bend", "keys": [{"time": 0, "transform": "rest"}]})"))
                .find("same file names as transforms[0]"),
            std::string::npos);
}

TEST(MeshCheck, FindsNonFiniteCoordinates) {
  EXPECT_EQ(count_non_finite_coordinates("# hdeform\nv 0 1 2\nv nan 1 -inf\nf 1 2 3\n", "obj"), 2u);
  EXPECT_EQ(count_non_finite_coordinates("# information\nv 0 1 2\n", "obj"), 0u);
  EXPECT_EQ(count_non_finite_coordinates("OFF\n2 0 0\n0 0 0\n1 -nan 0\n", "off"), 1u);
  EXPECT_EQ(count_non_finite_coordinates(
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nend_header\ninf 0 0\n", "ply"),
            1u);
  EXPECT_FALSE(count_non_finite_coordinates("ply\nformat binary_little_endian 1.0\nend_header\n", "ply"));
  EXPECT_THROW(count_non_finite_coordinates("nope", "glb"), CliError);
  // A GLB with two positions, one NaN.
  const std::string json =
      R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":24}],"bufferViews":[{"buffer":0,"byteLength":24}],)"
      R"("accessors":[{"bufferView":0,"componentType":5126,"count":2,"type":"VEC3"}],)"
      R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]})";
  std::string padded = json;
  while (padded.size() % 4) padded += ' ';
  const float p[6] = {0, 1, 2, std::numeric_limits<float>::quiet_NaN(), 0, 0};
  auto u32 = [](std::string& s, std::uint32_t v) { s.append(reinterpret_cast<const char*>(&v), 4); };
  std::string glb = "glTF";
  u32(glb, 2);
  u32(glb, static_cast<std::uint32_t>(12 + 8 + padded.size() + 8 + 24));
  u32(glb, static_cast<std::uint32_t>(padded.size()));
  u32(glb, 0x4E4F534A);
  glb += padded;
  u32(glb, 24);
  u32(glb, 0x004E4942);
  glb.append(reinterpret_cast<const char*>(p), 24);
  EXPECT_EQ(count_non_finite_coordinates(glb, "glb"), 1u);
  EXPECT_EQ(count_non_finite_floats(std::string(reinterpret_cast<const char*>(p), 24)), 1u);
}

TEST(OutputPath, StaysInsideTheFolder) {
  const fs::path dir = fs::temp_directory_path() / ("hdeform-job-test-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "sub");
  EXPECT_EQ(output_path_inside(dir, "a.glb"), fs::canonical(dir) / "a.glb");
  EXPECT_THROW(output_path_inside(dir, "../a.glb"), CliError);
  EXPECT_THROW(output_path_inside(dir, "sub/a.glb"), CliError);
  EXPECT_THROW(output_path_inside(dir, ".."), CliError);
  EXPECT_THROW(output_path_inside(dir, ""), CliError);
  EXPECT_THROW(output_path_inside(dir, "-rf"), CliError);
  EXPECT_THROW(output_path_inside(dir, std::string(256, 'a')), CliError);
  EXPECT_NO_THROW(output_path_inside(dir, std::string(251, 'a') + ".glb"));
  fs::create_symlink("/etc/passwd", dir / "link.glb");
  EXPECT_THROW(output_path_inside(dir, "link.glb"), CliError);
  fs::remove_all(dir);
}
