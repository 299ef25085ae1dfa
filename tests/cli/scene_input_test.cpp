// Scene inputs are refused or read exactly (docs/scenes.md "Render scenes", "Meshes"): TOML
// nested too deep, outputs that name an input, meshes and environment maps that would be
// misread, files that are not regular files, values that are not what they claim; each with one
// line naming the file, exit status 2, and every input and earlier output left byte-identical.
#include <sys/stat.h>

#include <map>

#include "cli_fixture.h"
#include "stf/geometry/mesh.h"
#include "stf/geometry/shipped_meshes.h"

namespace {

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void write(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

// A PFM latitude-longitude map of width x height grey pixels.
std::string pfm(int width, int height) {
  std::string b = "PF\n" + std::to_string(width) + " " + std::to_string(height) + "\n-1.0\n";
  const float v = 0.5f;
  for (int i = 0; i < 3 * width * height; ++i) b.append(reinterpret_cast<const char*>(&v), sizeof v);
  return b;
}

// A scene of a mesh (ball.obj) under an environment map (sky.pfm), 4 x 4 pixels.
std::string scene_text(const std::string& mesh = "ball.obj", const std::string& extra_camera = "") {
  return "[camera]\nposition = [0, 0, 3]\nwidth = 4\nheight = 4\n" + extra_camera +
         "[light]\nenvironment = \"sky.pfm\"\n[[media]]\nname = \"m\"\nsigma_s = 2\nsigma_a = 0.1\ng = 0.3\n"
         "[[objects]]\nmesh = \"" + mesh + "\"\nmedium = \"m\"\n";
}

class SceneInputs : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    write(out("ball.obj"), stf::geometry::obj_text(stf::geometry::icosphere(0.5, 1)));
    write(out("sky.pfm"), pfm(8, 4));
    write(out("scene.toml"), scene_text());
  }
  // Runs the shell command `command`; returns its exit status and stderr.
  Result shell(const std::string& command) {
    const std::string err = (dir_ / "stderr.txt").string();
    const int raw = std::system((command + " 2>'" + err + "' >/dev/null").c_str());
    const std::string text = bytes_of(err);
    fs::remove(err);
    return {WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw), text};
  }
  // Runs stf with `args`; expects exit 2, one line holding each of `names`, and every file of the
  // test folder as it was.
  // Returns the line.
  std::string expect_refused(const std::string& args, const std::vector<std::string>& names) {
    return expect_refused_shell(std::string(STF_BINARY) + " " + args, names);
  }
  std::string expect_refused_shell(const std::string& args, const std::vector<std::string>& names) {
    std::map<std::string, std::string> before;
    for (const auto& e : fs::directory_iterator(dir_))
      if (e.is_regular_file()) before[e.path().string()] = bytes_of(e.path().string());
    const Result r = shell(args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << "\n" << r.err;
    for (const std::string& n : names) EXPECT_NE(r.err.find(n), std::string::npos) << args << "\n" << r.err;
    std::map<std::string, std::string> after;
    for (const auto& e : fs::directory_iterator(dir_))
      if (e.is_regular_file()) after[e.path().string()] = bytes_of(e.path().string());
    EXPECT_EQ(after, before) << args;
    return r.err;
  }
  std::string render(const std::string& scene = "") {
    return "render " + (scene.empty() ? out("scene.toml") : scene) + " --spp 1 --method brute --quiet";
  }
};

TEST_F(SceneInputs, TomlNestedTooDeepIsRefusedBeforeItIsParsed) {
  const int deep = 10000;
  write(out("deep.toml"), "a = " + std::string(deep, '[') + std::string(deep, ']') + "\n");
  std::string dotted = "a";
  for (int i = 0; i < deep; ++i) dotted += ".b";
  write(out("dotted.toml"), dotted + " = 1\n");
  write(out("old.h5"), "an earlier output");
  for (const std::string file : {"deep.toml", "dotted.toml"}) {
    expect_refused(render(out(file)) + " -o " + out("old.h5"), {out(file) + ":1:", "64"});
    expect_refused("build " + out(file) + " --plan-only", {out(file) + ":1:", "64"});
    expect_refused("--config " + out(file) + " precompute -o " + out("old.h5"), {"--config", out(file), "64"});
  }
}

TEST_F(SceneInputs, NoOutputMayNameAnInputOfTheSameCommand) {
  for (const std::string option : {"-o", "--png", "--json", "--exr"})
    for (const std::string input : {"scene.toml", "ball.obj", "sky.pfm"}) {
      std::string args = render() + " " + option + " " + out(input);
      if (option != "-o") args += " -o " + out("image.h5");
      expect_refused(args, {option, out(input), "same file"});
    }
  write(out("render.toml"), "[render]\nspp = 1\nmethod = \"brute\"\n");
  expect_refused("--config " + out("render.toml") + " render " + out("scene.toml") + " -o " + out("render.toml"),
                 {"-o", "--config", "same file"});
  write(out("medium.toml"), "[precompute]\nsigma_s = 1\nsigma_a = 0.1\ng = 0\npaths = 100\n");
  expect_refused("--config " + out("medium.toml") + " precompute -o " + out("medium.toml"), {"-o", "--config", "same file"});
  EXPECT_FALSE(fs::exists(out("image.h5")));
}

TEST_F(SceneInputs, MeshesThatWouldBeMisreadAreRefusedByLine) {
  const std::string tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
  const std::vector<std::pair<std::string, std::string>> meshes = {
      {"v nan 0 0\n" + tetra, "bad.obj:1: 'nan' is not finite"},
      {"v inf 0 0\n" + tetra, "bad.obj:1: 'inf' is not finite"},
      {"v x y z\n" + tetra, "bad.obj:1: 'x' is not a number"},
      {"v 0 0\n" + tetra, "bad.obj:1: a vertex needs three numbers"},
      {tetra + "f 1 2 99999999999999999999\n", "bad.obj:5: the vertex index"},
      {tetra + "f 1 3 2 999999\n", "bad.obj:5: the face names vertex 999999"},
  };
  for (const auto& [text, what] : meshes) {
    write(out("bad.obj"), text);
    write(out("bad.toml"), scene_text("bad.obj"));
    expect_refused(render(out("bad.toml")) + " -o " + out("image.h5"), {out("bad.toml") + ":", what});
  }
  // Placed beyond what float tracing represents: refused, not rendered as sky.
  write(out("far.toml"), scene_text() + "scale = 1e6\ntranslate = [0, 0, 1e9]\n");
  expect_refused(render(out("far.toml")) + " -o " + out("image.h5"), {"far.toml", "beyond +-1e+09"});
}

TEST_F(SceneInputs, MeshesAndMapsThatAreNotRegularFilesAreRefusedAsSuch) {
  ASSERT_EQ(::mkfifo(out("pipe.obj").c_str(), 0600), 0);
  fs::create_directories(out("folder.obj"));
  for (const std::string mesh : {"pipe.obj", "folder.obj", "/dev/zero"}) {
    write(out("s.toml"), scene_text(mesh));
    const std::string line = expect_refused(render(out("s.toml")) + " -o " + out("image.h5"), {"s.toml:", "objects[0].mesh"});
    EXPECT_EQ(line.find("no such file"), std::string::npos) << line;
  }
  std::string map_scene = scene_text();
  map_scene.replace(map_scene.find("sky.pfm"), 7, "/dev/zero");
  write(out("s.toml"), map_scene);
  expect_refused(render(out("s.toml")) + " -o " + out("image.h5"), {"light.environment", "not a regular file"});
}

TEST_F(SceneInputs, AnMtllibThatIsAFifoIsNeverOpened) {
  ASSERT_EQ(::mkfifo(out("pipe.mtl").c_str(), 0600), 0);
  write(out("ball.obj"), "mtllib pipe.mtl\nusemtl stone\n" + bytes_of(out("ball.obj")));
  const Result ok = shell("timeout 60 " + std::string(STF_BINARY) + " " + render() + " -o " + out("image.h5"));
  EXPECT_EQ(ok.status, 0) << ok.err;
  EXPECT_TRUE(fs::exists(out("image.h5")));
}

TEST_F(SceneInputs, EnvironmentMapsAreCheckedAgainstTheirSizeBeforeAnyPixelIsAllocated) {
  write(out("huge.pfm"), "PF\n18000 18000\n-1.0\n" + std::string(1000, '\1'));
  const std::string full = pfm(8, 4);
  write(out("short.pfm"), full.substr(0, full.size() - 40));
  for (const std::string map : {"huge.pfm", "short.pfm"}) {
    std::string text = scene_text();
    text.replace(text.find("sky.pfm"), 7, map);
    write(out("s.toml"), text);
    // Under 1 GiB of address space the 18000 x 18000 map's 3.9 GB could not even be tried.
    expect_refused_shell("bash -c 'ulimit -v 1048576; exec " + std::string(STF_BINARY) + " " + render(out("s.toml")) +
                             " -o " + out("image.h5") + "'",
                         {map, "truncated"});
  }
}

TEST_F(SceneInputs, ValuesAreReadForWhatTheyAreWithMessagesThatSayWhatIsWrong) {
  const std::vector<std::pair<std::string, std::string>> cameras = {
      {"look_at = [0, 1e300, 0]\n", "camera.look_at: a coordinate beyond"},
      {"up = [0, 0, 1e300]\n", "must not be parallel"},
      {"up = [0, 0, 0]\n", "camera.up: must not be 0"},
  };
  for (const auto& [line, what] : cameras) {
    write(out("s.toml"), scene_text("ball.obj", line));
    expect_refused(render(out("s.toml")) + " -o " + out("image.h5"), {"s.toml:", what});
  }
  std::string wide = scene_text();
  wide.replace(wide.find("width = 4"), 9, "width = 1.5");
  write(out("s.toml"), wide);
  expect_refused(render(out("s.toml")) + " -o " + out("image.h5"), {"s.toml:", "camera.width: must be a whole number"});
  // Directions of any finite length but 0 are directions.
  write(out("s.toml"), scene_text("ball.obj", "up = [0, 1e-200, 0]\n"));
  EXPECT_EQ(stf(render(out("s.toml")) + " -o " + out("image.h5")).status, 0);
  std::string named = scene_text();
  named.replace(named.find("name = \"m\""), 10, "name = \"m\\u0000x\"");
  named.replace(named.find("medium = \"m\""), 12, "medium = \"m\\u0000x\"");
  write(out("s.toml"), named);
  expect_refused(render(out("s.toml")) + " -o " + out("image.h5"), {"media[0].name: holds a control character"});
  write(out("recipe.toml"), "[[media]]\nname = \"m\\u0000\"\nsigma_s = 1\nsigma_a = 0.1\ng = 0\nsize = 1\n");
  expect_refused("build " + out("recipe.toml") + " --plan-only", {"recipe.toml:2:", "media[0].name: holds a control character"});
  write(out("both.toml"), scene_text() + "shape = \"sphere\"\n");
  expect_refused(render(out("both.toml")) + " -o " + out("image.h5"), {"objects[0]: give either"});
}

// A first Ctrl-C ends the command within a second wherever it is: reading a mesh of 1.3M
// triangles, building Embree's tree or the distance grid (0.02 s while reading, up to 0.6 s in
// the grid of a 2M-triangle mesh, measured alone; the bound leaves room for a loaded machine).
TEST_F(SceneInputs, AFirstInterruptEndsMeshReadingAndTheGridWithinASecond) {
  write(out("ball.obj"), stf::geometry::obj_text(stf::geometry::icosphere(0.5, 8)));
  for (int ms : {200, 1500, 4000}) {
    double seconds = 0;
    const int status = interrupt_after({"render", out("scene.toml"), "--spp", "1", "--method", "brute", "--quiet", "-o",
                                        out("image.h5")},
                                       ms, &seconds);
    EXPECT_EQ(status, 130) << "after " << ms << " ms";
    EXPECT_LT(seconds, 2.0) << "after " << ms << " ms";
    EXPECT_FALSE(fs::exists(out("image.h5")));
    expect_no_litter("interrupted after " + std::to_string(ms) + " ms", "image.h5.");
  }
}

}  // namespace

namespace {

// A C-order .npy of `shape` with the raw little-endian `data` and dtype `descr` (format 1.0).
std::string npy(const std::string& descr, const std::string& shape, const std::string& data, bool fortran = false) {
  std::string header = "{'descr': '" + descr + "', 'fortran_order': " + (fortran ? "True" : "False") + ", 'shape': " + shape + ", }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  const std::uint16_t n = std::uint16_t(header.size());
  return std::string("\x93NUMPY\x01\x00", 8) + std::string(reinterpret_cast<const char*>(&n), 2) + header + data;
}

std::string floats(std::vector<float> v) { return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(float)); }

// A scene whose medium takes `grid` (lines of the [[media]] table) and whose object is its box.
std::string grid_scene(const std::string& grid) {
  return "[camera]\nposition = [0, 0, 3]\nwidth = 4\nheight = 4\n[[media]]\nname = \"m\"\nsigma_s = 2\nsigma_a = 0.1\n"
         "g = 0.3\n" + grid + "[[objects]]\nmedium = \"m\"\n";
}

}  // namespace

// Every bad grid a scene can name: one line naming the scene's line, the key, the file where
// there is one and what is wrong; nothing written.
TEST_F(SceneInputs, BadGridsAreRefusedInOneLine) {
  const std::string good = floats(std::vector<float>(8, 1.0f));
  write(out("good.npy"), npy("<f4", "(2, 2, 2)", good));
  write(out("int.npy"), npy("<i4", "(2, 2, 2)", good));
  write(out("flat.npy"), npy("<f4", "(8,)", good));
  write(out("zero.npy"), npy("<f4", "(2, 0, 2)", ""));
  write(out("fortran.npy"), npy("<f4", "(2, 2, 2)", good, true));
  write(out("short.npy"), npy("<f4", "(2, 2, 2)", good.substr(0, 12)));
  std::vector<float> negative(8, 1.0f), nan(8, 1.0f);
  negative[5] = -1, nan[3] = std::nanf("");
  write(out("negative.npy"), npy("<f4", "(2, 2, 2)", floats(negative)));
  write(out("nan.npy"), npy("<f4", "(2, 2, 2)", floats(nan)));
  write(out("empty.npy"), npy("<f4", "(2, 2, 2)", floats(std::vector<float>(8, 0.0f))));
  write(out("huge.npy"), npy("<f4", "(100000, 100000, 100000)", good));
  write(out("not.vdb"), "not a vdb file");
  const std::string box = "bounds = [[-1, -1, -1], [1, 1, 1]]\n";
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
      {"grid = \"missing.npy\"\n" + box, {"media[0].grid: no such file", "missing.npy"}},
      {"grid = \"good.npy\"\n", {"media[0].bounds: a .npy grid needs bounds"}},
      {"grid = \"not.vdb\"\nbounds = [[-1, -1, -1], [1, 1, 1]]\n", {"media[0].bounds: for a .npy grid only"}},
      {"grid = \"good.npy\"\nbounds = [[1, -1, -1], [-1, 1, 1]]\n", {"media[0].bounds: inverted"}},
      {box, {"media[0].bounds: places a grid; there is none"}},
      {"grid = \"int.npy\"\n" + box, {"media[0].grid:", "int.npy", "<i4"}},
      {"grid = \"flat.npy\"\n" + box, {"media[0].grid:", "flat.npy"}},
      {"grid = \"zero.npy\"\n" + box, {"media[0].grid:", "zero.npy"}},
      {"grid = \"fortran.npy\"\n" + box, {"media[0].grid:", "fortran.npy"}},
      {"grid = \"short.npy\"\n" + box, {"media[0].grid:", "short.npy"}},
      {"grid = \"negative.npy\"\n" + box, {"media[0].grid:", "negative.npy"}},
      {"grid = \"nan.npy\"\n" + box, {"media[0].grid:", "nan.npy"}},
      {"grid = \"empty.npy\"\n" + box, {"media[0].grid:", "empty.npy"}},
      {"grid = \"huge.npy\"\n" + box, {"media[0].grid:", "huge.npy"}},
      {"grid = \"not.vdb\"\n", {"media[0].grid:", "not.vdb"}},
  };
  for (const auto& [lines, what] : cases) {
    write(out("g.toml"), grid_scene(lines));
    std::vector<std::string> names = what;
    names.push_back("g.toml:");
    expect_refused(render(out("g.toml")) + " -o " + out("image.h5"), names);
  }
  write(out("g.toml"), grid_scene("grid = \"good.npy\"\n" + box));
  EXPECT_EQ(stf(render(out("g.toml")) + " -o " + out("image.h5")).status, 0);
}
