#include "mav/sim/presets.h"

#include <cmath>
#include <sstream>

#include "mav/common/text.h"
#include "random.h"

namespace mav::sim {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

Material Mat(TexturePattern pattern, float albedo, float contrast, float texel,
             float emission = 0) {
  Material m;
  m.pattern = pattern;
  m.albedo = albedo;
  m.contrast = contrast;
  m.texel_size_m = texel;
  m.emission = emission;
  return m;
}

Eigen::Matrix3d WallFrame(int axis, int sign) {
  // Rectangle frame for a decal on a wall whose inward normal is sign * e_axis.
  Eigen::Matrix3d r;
  const Vector3d n = sign * Vector3d::Unit(axis);
  const Vector3d up = axis == 2 ? Vector3d::UnitX() : Vector3d::UnitZ();
  const Vector3d x = up.cross(n);
  r.col(0) = x;
  r.col(1) = n.cross(x);
  r.col(2) = n;
  return r;
}

}  // namespace

double ImageEffects::GainAt(double t_s, uint64_t seed) const {
  if (gain_amplitude == 0) return base_gain;
  internal::Rng rng(internal::HashCombine(seed, 0x6a1eULL));
  const double p1 = rng.Uniform(0, 2 * M_PI), p2 = rng.Uniform(0, 2 * M_PI);
  const double s = 0.7 * std::sin(2 * M_PI * t_s / gain_period_s + p1) +
                   0.3 * std::sin(2 * M_PI * t_s / (0.37 * gain_period_s) + p2);
  return base_gain * (1.0 + gain_amplitude * s);
}

const std::vector<std::string>& PresetNames() {
  static const std::vector<std::string> kNames = {"room-easy", "room-medium", "room-hard", "plant"};
  return kNames;
}

std::shared_ptr<World> BuildRoomWorld(const RoomStyle& style) {
  auto world = std::make_shared<World>();
  World& w = *world;
  const float poor = static_cast<float>(style.poor_texture_contrast);
  // Materials.
  const int floor = w.AddMaterial(
      Mat(TexturePattern::kSpeckle, 0.42f, style.poor_surfaces >= 2 ? poor : 0.2f, 0.004f));
  const int wall_bricks = w.AddMaterial(Mat(TexturePattern::kBricks, 0.5f, 0.2f, 0.004f));
  const int wall_blobs = w.AddMaterial(Mat(TexturePattern::kBlobs, 0.55f, 0.22f, 0.004f));
  const int wall_noise = w.AddMaterial(
      Mat(TexturePattern::kNoise, 0.6f, style.poor_surfaces >= 1 ? poor : 0.18f, 0.004f));
  const int wall_planks = w.AddMaterial(Mat(TexturePattern::kPlanks, 0.45f, 0.2f, 0.004f));
  const int ceiling = w.AddMaterial(
      Mat(TexturePattern::kNoise, 0.7f, style.poor_surfaces >= 1 ? poor : 0.12f, 0.004f));
  const int crate = w.AddMaterial(Mat(TexturePattern::kPlanks, 0.55f, 0.22f, 0.003f));
  const int poster = w.AddMaterial(Mat(TexturePattern::kBlobs, 0.5f, 0.3f, 0.003f));
  const int metal = w.AddMaterial(Mat(TexturePattern::kSpeckle, 0.32f, 0.12f, 0.002f));
  const int pipe = w.AddMaterial(Mat(TexturePattern::kNoise, 0.62f, 0.1f, 0.002f));
  const int box_noise = w.AddMaterial(Mat(TexturePattern::kNoise, 0.4f, 0.25f, 0.003f));

  // Shell: interior [-4, 4] x [-4, 4] x [0, 3], slabs 0.2 m thick.
  const double t = 0.2;
  w.AddAlignedBox(Vector3d(-4 - t, -4 - t, -t), Vector3d(4 + t, 4 + t, 0), floor);
  w.AddAlignedBox(Vector3d(-4 - t, -4 - t, 3), Vector3d(4 + t, 4 + t, 3 + t), ceiling);
  w.AddAlignedBox(Vector3d(-4 - t, -4 - t, 0), Vector3d(-4, 4 + t, 3), wall_bricks);
  w.AddAlignedBox(Vector3d(4, -4 - t, 0), Vector3d(4 + t, 4 + t, 3), wall_blobs);
  w.AddAlignedBox(Vector3d(-4, -4 - t, 0), Vector3d(4, -4, 3), wall_noise);
  w.AddAlignedBox(Vector3d(-4, 4, 0), Vector3d(4, 4 + t, 3), wall_planks);
  w.SetBounds(Eigen::AlignedBox3d(Vector3d(-4 - t, -4 - t, -t), Vector3d(4 + t, 4 + t, 3 + t)));

  // Posters on the plain wall (decals 2 mm off the wall, facing into the room).
  w.AddRectangle(Vector3d(-1.5, -3.998, 1.5), WallFrame(1, 1), Vector2d(0.6, 0.45), poster);
  w.AddRectangle(Vector3d(2.2, -3.998, 1.3), WallFrame(1, 1), Vector2d(0.5, 0.7), poster);

  // Central stack of boxes (the camera's usual point of interest), one of them rotated.
  w.AddAlignedBox(Vector3d(-0.45, -0.4, 0), Vector3d(0.45, 0.4, 0.7), crate);
  w.AddBox(Vector3d(0.05, 0.0, 0.9), geometry::RotationFromRollPitchYaw(0, 0, 0.35),
           Vector3d(0.3, 0.25, 0.2), box_noise);
  // Crates and boxes along the walls.
  w.AddAlignedBox(Vector3d(2.8, 2.6, 0), Vector3d(3.9, 3.9, 0.9), crate);
  w.AddAlignedBox(Vector3d(3.1, 2.9, 0.9), Vector3d(3.8, 3.7, 1.5), box_noise);
  w.AddAlignedBox(Vector3d(-3.9, -3.9, 0), Vector3d(-2.9, -3.0, 1.2), box_noise);
  w.AddBox(Vector3d(3.3, -2.0, 0.4), geometry::RotationFromRollPitchYaw(0, 0, -0.5),
           Vector3d(0.45, 0.35, 0.4), crate);
  w.AddAlignedBox(Vector3d(-1.0, 3.3, 0), Vector3d(0.2, 3.9, 0.6), crate);
  // Shelf against the brick wall.
  w.AddShelf(Vector3d(-3.7, 1.2, 0), M_PI / 2, 1.6, 0.5, 2.0, 4, metal, crate);
  w.AddAlignedBox(Vector3d(-3.85, 0.7, 0.14), Vector3d(-3.55, 1.0, 0.45), poster);
  w.AddAlignedBox(Vector3d(-3.9, 1.3, 0.64), Vector3d(-3.6, 1.8, 0.9), box_noise);
  // A ladder leaning against the plank wall.
  w.AddLadder(Vector3d(1.6, 3.25, 0), Vector3d(1.6, 3.92, 2.7), 0.45, 0.28, metal);
  // Pipes: a horizontal run along the plain wall, a riser, thin conduits (fine structures).
  w.AddPipe({Vector3d(-3.9, -3.85, 2.55), Vector3d(3.85, -3.85, 2.55), Vector3d(3.85, -3.85, 0)},
            0.05, pipe);
  w.AddPipe({Vector3d(-3.9, -3.75, 2.3), Vector3d(2.0, -3.75, 2.3)}, 0.015, pipe);
  w.AddPipe({Vector3d(3.9, -1.0, 2.75), Vector3d(3.9, 3.0, 2.75)}, 0.04, pipe);
  w.AddPipe({Vector3d(1.0, 1.2, 3.0), Vector3d(1.0, 1.2, 2.2), Vector3d(-1.2, 1.2, 2.2)}, 0.012,
            pipe);
  // A table.
  w.AddAlignedBox(Vector3d(-2.6, -2.8, 0.72), Vector3d(-1.2, -2.0, 0.76), crate);
  for (double x : {-2.55, -1.25}) {
    for (double y : {-2.75, -2.05}) {
      w.AddAlignedBox(Vector3d(x - 0.025, y - 0.025, 0), Vector3d(x + 0.025, y + 0.025, 0.72),
                      metal);
    }
  }

  if (style.lamps) {
    const int lamp = w.AddMaterial(Mat(TexturePattern::kUniform, 0.9f, 0, 0.01f, 2.5f));
    w.AddRectangle(Vector3d(-1.5, 1.5, 2.998), WallFrame(2, -1), Vector2d(0.6, 0.15), lamp);
    w.AddRectangle(Vector3d(1.5, -1.5, 2.998), WallFrame(2, -1), Vector2d(0.6, 0.15), lamp);
    w.AddRectangle(Vector3d(3.998, 0.5, 2.3), WallFrame(0, -1), Vector2d(0.25, 0.12), lamp);
  }
  if (style.window) {
    const int window = w.AddMaterial(Mat(TexturePattern::kNoise, 0.9f, 0.05f, 0.02f, 3.0f));
    w.AddRectangle(Vector3d(3.998, -0.8, 1.6), WallFrame(0, -1), Vector2d(1.0, 0.7), window);
  }
  if (style.dark_curtain) {
    const int dark = w.AddMaterial(Mat(TexturePattern::kNoise, 0.04f, 0.015f, 0.004f));
    w.AddRectangle(Vector3d(-3.998, -1.5, 1.4), WallFrame(0, 1), Vector2d(1.2, 1.35), dark);
  }
  w.lighting().background = 0.0;
  return world;
}

std::shared_ptr<World> BuildPlantWorld() {
  auto world = std::make_shared<World>();
  World& w = *world;
  const int gravel = w.AddMaterial(Mat(TexturePattern::kSpeckle, 0.4f, 0.2f, 0.02f));
  const int concrete = w.AddMaterial(Mat(TexturePattern::kNoise, 0.55f, 0.2f, 0.015f));
  const int bricks = w.AddMaterial(Mat(TexturePattern::kBricks, 0.45f, 0.2f, 0.008f));
  const int tank = w.AddMaterial(Mat(TexturePattern::kBlobs, 0.6f, 0.15f, 0.015f));
  const int steel = w.AddMaterial(Mat(TexturePattern::kSpeckle, 0.35f, 0.15f, 0.005f));
  const int pipe = w.AddMaterial(Mat(TexturePattern::kNoise, 0.55f, 0.15f, 0.006f));
  const int panel = w.AddMaterial(Mat(TexturePattern::kPlanks, 0.5f, 0.2f, 0.01f));

  w.AddAlignedBox(Vector3d(-25, -25, -0.3), Vector3d(25, 25, 0), gravel);
  w.SetBounds(Eigen::AlignedBox3d(Vector3d(-25, -25, -0.3), Vector3d(25, 25, 40)));

  // Perimeter walls (partial, so the site is open), and two buildings.
  w.AddWall(Vector2d(-24, -24), Vector2d(10, -24), 0, 6, 0.4, bricks);
  w.AddWall(Vector2d(-24, -20), Vector2d(-24, 18), 0, 6, 0.4, bricks);
  w.AddWall(Vector2d(5, 24), Vector2d(24, 24), 0, 8, 0.4, concrete);
  w.AddAlignedBox(Vector3d(12, 8, 0), Vector3d(22, 20, 14), concrete);
  w.AddAlignedBox(Vector3d(-22, 6, 0), Vector3d(-14, 16, 9), panel);
  // Tanks.
  w.AddTank(Vector3d(-8, -12, 0), 4.0, 12.0, tank);
  w.AddTank(Vector3d(2, -14, 0), 3.0, 10.0, tank);
  w.AddTank(Vector3d(12, -10, 0), 3.5, 15.0, tank);
  w.AddTank(Vector3d(-10, 12, 0), 2.5, 8.0, tank);
  // Towers (lattice) with a chimney.
  w.AddTower(Vector3d(0, 8, 0), 3.0, 24.0, 0.15, steel);
  w.AddTower(Vector3d(18, -20, 0), 2.5, 30.0, 0.12, steel);
  w.AddCylinder(Vector3d(-16, -4, 0), Vector3d(-16, -4, 35), 1.2, concrete);
  // Pipe racks between the tanks: thick process pipes and thin lines (fine structures).
  w.AddPipe({Vector3d(-8, -7.9, 5), Vector3d(-8, 0, 5), Vector3d(0, 0, 5), Vector3d(0, 6.4, 5)},
            0.3, pipe);
  w.AddPipe({Vector3d(2, -10.9, 3), Vector3d(2, -4, 3), Vector3d(12, -4, 3), Vector3d(12, -6.4, 3)},
            0.25, pipe);
  w.AddPipe({Vector3d(-4, 0.5, 6), Vector3d(12, 0.5, 6), Vector3d(12, 7.9, 6)}, 0.08, pipe);
  w.AddPipe({Vector3d(-4, -0.6, 4.2), Vector3d(10, -0.6, 4.2)}, 0.05, pipe);
  w.AddPipe({Vector3d(-10, 9.4, 2), Vector3d(-10, 2, 2), Vector3d(-15, 2, 2)}, 0.15, pipe);
  // Pipe rack supports.
  for (double x : {-6.0, -2.0, 2.0, 6.0, 10.0}) {
    w.AddAlignedBox(Vector3d(x - 0.15, -0.8, 0), Vector3d(x + 0.15, 0.8, 6.4), steel);
  }
  w.lighting().background = 0.85;
  return world;
}

Result<Preset> MakePreset(const std::string& name) {
  Preset p;
  p.name = name;
  RoomStyle style;
  if (name == "room-easy") {
    p.full_frames = 2839;
    p.profile = MotionProfile::kEasy;
    p.effects.gain_amplitude = 0.05;
    p.effects.gain_period_s = 30;
    p.effects.noise_sigma = 1.0;
  } else if (name == "room-medium") {
    p.full_frames = 1559;
    p.profile = MotionProfile::kMedium;
    style.poor_surfaces = 1;
    style.poor_texture_contrast = 0.04;
    style.lamps = true;
    p.effects.gain_amplitude = 0.2;
    p.effects.gain_period_s = 15;
    p.effects.noise_sigma = 2.0;
    p.effects.shutter_s = 0.004;
    p.effects.max_blur_samples = 3;
  } else if (name == "room-hard") {
    p.full_frames = 2079;
    p.profile = MotionProfile::kHard;
    style.poor_surfaces = 2;
    style.poor_texture_contrast = 0.03;
    style.lamps = true;
    style.window = true;
    style.dark_curtain = true;
    p.effects.gain_amplitude = 0.35;
    p.effects.gain_period_s = 8;
    p.effects.noise_sigma = 3.0;
    p.effects.shutter_s = 0.008;
    p.effects.max_blur_samples = 4;
  } else if (name == "plant") {
    p.full_frames = 2000;
    p.profile = MotionProfile::kPlant;
    p.effects.gain_amplitude = 0.1;
    p.effects.gain_period_s = 25;
    p.effects.noise_sigma = 1.5;
    p.effects.shutter_s = 0.003;
    p.effects.max_blur_samples = 3;
  } else {
    std::ostringstream msg;
    msg << "preset: unknown preset " << QuoteForError(name) << " (known: ";
    for (size_t i = 0; i < PresetNames().size(); ++i) msg << (i ? ", " : "") << PresetNames()[i];
    msg << ")";
    return Status::InvalidArgument(msg.str());
  }
  if (name == "plant") {
    p.world = BuildPlantWorld();
    p.flight_bounds = Eigen::AlignedBox3d(Vector3d(-20, -20, 2.0), Vector3d(20, 20, 14));
    p.min_clearance = 1.5;
    p.look_at = Vector3d(0, -2, 5);
  } else {
    p.world = BuildRoomWorld(style);
    p.flight_bounds = Eigen::AlignedBox3d(Vector3d(-3.2, -3.2, 0.6), Vector3d(3.2, 3.2, 2.3));
    p.min_clearance = 0.5;
    p.look_at = Vector3d(0, 0, 0.8);
  }
  return p;
}

}  // namespace mav::sim
