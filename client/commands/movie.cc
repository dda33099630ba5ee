// foam export --movie: a job's snapshots as a video. Frames come from the software renderer
// (render.h) and go to Debian's ffmpeg as raw RGB on a pipe, so nothing needs a display, a GPU
// or a browser.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "../commands.h"
#include "../render.h"

extern char** environ;

namespace activefoam::client {
namespace {

namespace fs = std::filesystem;

// The first executable NAME on $PATH, "" when there is none.
std::string findOnPath(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    // An empty entry is the working directory (GCC 12 warns falsely on assigning "." to dir).
    const std::string exe = (dir.empty() ? std::string(".") : dir) + "/" + name;
    if (::access(exe.c_str(), X_OK) == 0 && !fs::is_directory(exe)) return exe;
  }
  return "";
}

// ffmpeg reading raw RGB frames on its stdin and writing `out`.
class Ffmpeg {
 public:
  // `out` gets the container named by `gif` whatever its own name ends with.
  Ffmpeg(const std::string& exe, const std::string& out, int w, int h, double fps, bool gif) {
    std::vector<std::string> args = {
        exe,        "-hide_banner", "-nostdin", "-loglevel",
        "error",    "-y",           "-f",       "rawvideo",
        "-pix_fmt", "rgb24",        "-s",       std::to_string(w) + "x" + std::to_string(h),
        "-r",       fpsText(fps),   "-i",       "-"};
    if (gif) {
      // One palette for the whole movie, made from its own frames: GIF has 256 colours.
      args.insert(args.end(),
                  {"-vf", "split[a][b];[a]palettegen=stats_mode=full[p];[b][p]paletteuse", "-loop",
                   "0", "-f", "gif"});
    } else {
      // yuv420p: what players and browsers decode; +faststart: playable while downloading.
      args.insert(args.end(), {"-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4"});
    }
    args.push_back(out);
    int fds[2];
    // Close-on-exec: neither end may leak into ffmpeg (it would never see the end of its input)
    // or into anything else started meanwhile; dup2 onto its stdin clears the flag there.
    if (::pipe2(fds, O_CLOEXEC) != 0)
      throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fds[0], 0);
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, exe.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    ::close(fds[0]);
    if (rc != 0) {
      ::close(fds[1]);
      throw std::runtime_error("cannot start " + exe + ": " + std::strerror(rc));
    }
    fd_ = fds[1];
  }
  ~Ffmpeg() {
    if (fd_ >= 0) ::close(fd_);
    if (pid_ > 0) ::waitpid(pid_, nullptr, 0);
  }
  // False once ffmpeg stopped reading (it failed: its message is on stderr already).
  bool write(const Image& img) {
    const auto* p = reinterpret_cast<const char*>(img.rgb.data());
    std::size_t left = img.rgb.size();
    while (left > 0) {
      const ssize_t n = ::write(fd_, p, left);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return false;
      p += n;
      left -= static_cast<std::size_t>(n);
    }
    return true;
  }
  // ffmpeg's exit status after the last frame.
  int finish() {
    ::close(fd_);
    fd_ = -1;
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }

 private:
  static std::string fpsText(double fps) {
    std::ostringstream o;
    o << fps;
    return o.str();
  }
  pid_t pid_ = -1;
  int fd_ = -1;
};

// The video frames ffprobe counts in `file`; -1 when it cannot read the file as a movie (a
// missing trailer, a cut file: what ffmpeg leaves on a full disk though it exits 0).
long countFrames(const std::string& ffprobe, const std::string& file) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return -1;
  std::vector<std::string> args = {ffprobe,
                                   "-v",
                                   "error",
                                   "-count_frames",
                                   "-select_streams",
                                   "v:0",
                                   "-show_entries",
                                   "stream=nb_read_frames",
                                   "-of",
                                   "csv=p=0",
                                   file};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, ffprobe.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  ::close(fds[1]);
  std::string out;
  char buf[256];
  for (ssize_t n; rc == 0 && (n = ::read(fds[0], buf, sizeof buf)) != 0;) {
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) break;
    out.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  if (rc != 0) return -1;
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1;
  try {
    std::size_t used = 0;
    const long n = std::stol(out, &used);
    return n;
  } catch (const std::exception&) {
    return -1;
  }
}

bool parseSize(const std::string& s, int& w, int& h) {
  const auto x = s.find('x');
  if (x == std::string::npos) return false;
  try {
    std::size_t a = 0, b = 0;
    w = std::stoi(s.substr(0, x), &a);
    h = std::stoi(s.substr(x + 1), &b);
    if (a != x || b != s.size() - x - 1) return false;
  } catch (const std::exception&) {
    return false;
  }
  return w >= 64 && h >= 64 && w <= 7680 && h <= 4320;
}

// The text of a ramp's end, short: "0.125", "1.2e+03".
std::string shortNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

// The legend in the lower left: what the colours mean.
void drawLegend(Image& img, ColorBy by, double lo, double hi, bool two_spheroids, int scale) {
  const Rgb ink{0x1f, 0x23, 0x28};
  const int box = 7 * scale, y = img.height - 7 * scale - 4 * scale;
  int x = 4 * scale;
  if (by == ColorBy::Spheroid) {
    for (int label = 0; label < (two_spheroids ? 2 : 1); ++label) {
      fillRect(img, x, y, box, box, cellColor(ColorBy::Spheroid, 0, label, 0, 0, 0));
      x += box + 3 * scale;
      x += drawText(img, x, y, label == 0 ? "spheroid A" : "spheroid B", scale, ink) + 12 * scale;
    }
  } else if (by == ColorBy::Cell) {
    drawText(img, x, y, "colour: cell id", scale, ink);
  } else {
    x += drawText(img, x, y,
                  (by == ColorBy::Pressure ? "pressure " : "cell volume ") + shortNumber(lo), scale,
                  ink) +
         4 * scale;
    const int w = 40 * scale;
    for (int k = 0; k < w; ++k)
      fillRect(img, x + k, y, 1, box, cellColor(by, 0, 0, lo + (hi - lo) * k / (w - 1), lo, hi));
    x += w + 4 * scale;
    drawText(img, x, y, shortNumber(hi) + (by == ColorBy::Pressure ? " kPa" : " um^3"), scale, ink);
  }
}

}  // namespace

int runMovie(Conn& conn, const ExportOptions& o) {
  const std::string what = "export --movie " + o.id;
  auto fail = [&](int code, const std::string& why) {
    std::cerr << "foam: " << what << ": " << why << "\n";
    return code;
  };
  if (o.movie_file.empty())
    return fail(kUsage, "no FILE: foam export --movie ID FILE.mp4 (or FILE.gif)");
  std::string ext = fs::path(o.movie_file).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (ext != ".mp4" && ext != ".gif")
    return fail(kUsage, "FILE " + o.movie_file + ": .mp4 or .gif, please");
  int width = 0, height = 0;
  if (!parseSize(o.size, width, height))
    return fail(kUsage, "--size " + o.size + ": WIDTHxHEIGHT, each 64 to 7680 (x 4320)");
  width += width % 2;  // yuv420p halves the chroma planes: even sizes only
  height += height % 2;
  ColorBy by = ColorBy::Spheroid;
  if (!parseColorBy(o.color, by))
    return fail(kUsage, "--color " + o.color + ": spheroid, cell, pressure or volume");

  v1::GetResultsRequest req;
  req.set_job_id(o.id);
  v1::JobResults r;
  {
    auto ctx = conn.ctx();
    const grpc::Status st = conn.stub->GetResults(ctx.get(), req, &r);
    if (!st.ok()) return rpcError(st, what);
  }
  if (r.snapshots_size() == 0)
    return fail(kUsage,
                "the job has no snapshots to make a movie of (its spec's "
                "snapshot_every_s = 0, or none recorded yet)");
  const std::string ffmpeg = findOnPath("ffmpeg"), ffprobe = findOnPath("ffprobe");
  if (ffmpeg.empty() || ffprobe.empty())
    return fail(kUsage,
                "ffmpeg and ffprobe are not on PATH: apt-get install ffmpeg (Debian's package)");

  auto newCtx = [&] { return conn.ctx(); };
  // Pass 1: the box every frame fits in, and the colour ramp's range, over all snapshots:
  // the camera and the colours then stay put while the tissue moves.
  std::array<double, 6> box{};
  bool any = false, two_spheroids = false;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const v1::SnapshotInfo& info : r.snapshots()) {
    VtkMesh mesh;
    if (std::string err = fetchSnapshot(*conn.stub, newCtx, o.id, info, mesh); !err.empty())
      return fail(kJobNotOk, err);
    const auto b = meshBox(mesh);
    if (b[0] <= b[3]) {
      if (!any) box = b;
      extendBox(box, b);
      any = true;
    }
    for (int l : mesh.cell_label) two_spheroids = two_spheroids || l == 1;
    for (double v : cellValues(mesh, by))
      if (std::isfinite(v)) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
  }
  if (!any) return fail(kJobNotOk, "the job's snapshots hold no vertices");
  if (lo > hi) lo = hi = 0;
  const Camera camera = frameBox(box, static_cast<double>(width) / height);

  // A reader gone (ffmpeg failed) must end in its message, not in SIGPIPE.
  ::signal(SIGPIPE, SIG_IGN);
  const int scale = std::max(1, height / 200);
  const Rgb background{0xf4, 0xf6, 0xf9}, ink{0x1f, 0x23, 0x28};
  int frames = 0;
  // ffmpeg writes next to FILE and the result is renamed onto it once ffprobe has counted every
  // frame in it: a failure half way, or a movie without its trailer on a full disk (ffmpeg exits
  // 0 there), leaves no broken movie, and an older FILE stays until a new one replaces it. The
  // temporary's name is this process's own, created here: no file of the user's is touched.
  fs::path part;
  for (int attempt = 0; part.empty() && attempt < 100; ++attempt) {
    std::string suffix = ".";
    suffix.append(std::to_string(::getpid())).append("-").append(std::to_string(attempt));
    suffix.append(".part").append(ext);
    fs::path candidate = fs::path(o.movie_file).concat(suffix);
    const int fd = ::open(candidate.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd >= 0) {
      ::close(fd);
      part = candidate;
    } else if (errno != EEXIST) {
      return fail(kJobNotOk, "cannot write next to " + o.movie_file + ": " + std::strerror(errno));
    }
  }
  if (part.empty()) return fail(kJobNotOk, "cannot name a temporary file next to " + o.movie_file);
  struct RemovePart {
    fs::path path;
    ~RemovePart() {
      std::error_code ec;
      fs::remove(path, ec);
    }
  } remove_part{part};
  try {
    Ffmpeg encoder(ffmpeg, part.string(), width, height, o.fps, ext == ".gif");
    for (const v1::SnapshotInfo& info : r.snapshots()) {
      VtkMesh mesh;
      if (std::string err = fetchSnapshot(*conn.stub, newCtx, o.id, info, mesh); !err.empty())
        return fail(kJobNotOk, err);
      Image img(width, height, background);
      renderMesh(img, mesh, camera, by, lo, hi);
      drawText(img, 4 * scale, 4 * scale, formatSimTime(mesh.t_s), scale + 1, ink);
      const std::string id = "job " + o.id;
      drawText(img, width - textWidth(id, scale) - 4 * scale, 4 * scale, id, scale, ink);
      drawLegend(img, by, lo, hi, two_spheroids, scale);
      if (!encoder.write(img)) break;
      ++frames;
    }
    if (const int rc = encoder.finish(); rc != 0)
      return fail(kJobNotOk, "ffmpeg failed (exit " + std::to_string(rc) + ") writing " +
                                 o.movie_file + "; its message is above");
  } catch (const std::exception& e) {
    return fail(kJobNotOk, e.what());
  }
  if (const long counted = countFrames(ffprobe, part.string()); counted != frames)
    return fail(kJobNotOk, "the movie ffmpeg wrote is incomplete (" +
                               (counted < 0 ? std::string("ffprobe cannot read it")
                                            : std::to_string(counted) + " of " +
                                                  std::to_string(frames) + " frames") +
                               "; a full disk?): " + o.movie_file + " is left as it was");
  std::error_code ec;
  fs::rename(part, o.movie_file, ec);
  if (ec) return fail(kJobNotOk, "cannot write " + o.movie_file + ": " + ec.message());
  std::cerr << "foam: " << frames << " frame" << (frames == 1 ? "" : "s") << " at " << o.fps
            << " fps\n";
  std::cout << o.movie_file << "\n";
  return kOk;
}

}  // namespace activefoam::client
