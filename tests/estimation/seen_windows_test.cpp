// Windows the cameras saw as holes (issue 43): clipped pixels off the mesh whose rays leave
// the scene, ringed by one flat wall, against the wall and the hole they were drawn from.
#include <cstdio>

#include <gtest/gtest.h>

#include "estimation/envmap.h"
#include "estimation/path_tracer.h"
#include "estimation/seen_windows.h"
#include "tests/test_util.h"

namespace lp {
namespace {

using test::BlankView;
using test::LookAt;

constexpr double kWallY = 2;
/// The hole's x and z ranges in the wall.
constexpr double kX0 = 0.2, kX1 = 1.0, kZ0 = 1.0, kZ1 = 1.8;

/// A quad (two triangles) of corners a, b, c, d, grey.
Mesh Quad(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c, const Eigen::Vector3f& d) {
  Mesh m;
  m.positions = {a, b, c, d};
  m.albedo.assign(4, Eigen::Vector3f::Constant(0.5f));
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

/// A wall y = kWallY, x -2..2, z 0..3, facing -y, with the hole at [kX0, kX1] x [kZ0, kZ1]
/// when `hole` (else whole).
Mesh Wall(bool hole) {
  const float y = static_cast<float>(kWallY);
  const auto quad = [&](double x0, double x1, double z0, double z1) {
    return Quad({float(x0), y, float(z0)}, {float(x0), y, float(z1)}, {float(x1), y, float(z1)}, {float(x1), y, float(z0)});
  };
  Mesh m = quad(-2, 2, 0, hole ? kZ0 : 3);
  if (hole) {
    m.Append(quad(-2, 2, kZ1, 3));
    m.Append(quad(-2, kX0, kZ0, kZ1));
    m.Append(quad(kX1, 2, kZ0, kZ1));
  }
  ComputeVertexNormals(&m);
  return m;
}

/// Marks clipped off the mesh (and not valid) the pixels of `v` whose centre's ray `hits`; the count.
template <class F>
int ClipOff(View* v, F hits) {
  v->clipped_off.assign(v->valid.size(), 0);
  int n = 0;
  const Camera& c = v->camera;
  for (std::size_t p = 0; p < v->valid.size(); ++p)
    if (hits(c.center(), c.RayDirection(static_cast<double>(p % c.width), static_cast<double>(p / c.width))))
      v->clipped_off[p] = 1, v->valid[p] = 0, ++n;
  return n;
}

/// Whether a ray crosses the wall's plane inside [x0, x1] x [z0, z1].
bool ThroughWall(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double x0, double x1, double z0, double z1) {
  if (d.y() <= 0) return false;
  const Eigen::Vector3d p = o + (kWallY - o.y()) / d.y() * d;
  return p.x() > x0 && p.x() < x1 && p.z() > z0 && p.z() < z1;
}

/// The view from in front of the wall, its pixels whose rays pass through the hole's place
/// marked clipped off the mesh; how many in `clipped`.
View FrontViewOfTheHole(int* clipped) {
  View v = BlankView(LookAt({0.3, -1, 1.3}, {0.5, kWallY, 1.3}, 160, 120, 60));
  *clipped = ClipOff(&v, [](const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
    return ThroughWall(o, d, kX0, kX1, kZ0, kZ1);
  });
  return v;
}

TEST(SeenWindows, AHoleInAWallSeenBrightIsAWindowFacingTheRoom) {
  const RayTracer scene(Wall(true));
  std::vector<View> views{BlankView(LookAt({0.3, -1, 1.3}, {0.5, kWallY, 1.3}, 160, 120, 60)),
                          BlankView(LookAt({1.2, -0.8, 1.2}, {0.4, kWallY, 1.4}, 160, 120, 60))};
  for (View& v : views)
    ASSERT_GT(ClipOff(&v, [](const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
                return ThroughWall(o, d, kX0, kX1, kZ0, kZ1);
              }), 100);
  const std::vector<SeenWindow> seen = SeenWindows(views, scene);
  ASSERT_EQ(seen.size(), 1u) << "the two views' blobs are one window";
  EXPECT_NEAR(seen[0].normal.y(), -1, 1e-6) << seen[0].normal.transpose();
  EXPECT_NEAR(seen[0].centre.y(), kWallY, 1e-6);
  // The blob's mean pixel's ray: near the hole's centre (perspective moves it a little).
  EXPECT_LT((seen[0].centre - Eigen::Vector3d(0.5 * (kX0 + kX1), kWallY, 0.5 * (kZ0 + kZ1))).norm(), 0.06)
      << seen[0].centre.transpose();
  // Its extent (the portal next events aim through, the pane over the hole): the rectangle
  // holding the blob's outline on the wall, moved to the hole's edges, is the hole to 2 mm
  // (with the blob's pixel bounds, an oblique view's quadrilateral, 6 cm more; with its
  // border pixels' outer corners 1.1 cm).
  ASSERT_FALSE(seen[0].outline.empty());
  const Portal p = PortalAround(seen[0].outline, seen[0].centre, seen[0].normal, Eigen::Vector3d::UnitX());
  EXPECT_NEAR(std::abs(p.axis_u.x()), 1, 1e-6);
  const double x0 = p.centre.x() - p.half_u, x1 = p.centre.x() + p.half_u;
  const double z0 = p.centre.z() - p.half_v, z1 = p.centre.z() + p.half_v;
  EXPECT_NEAR(x0, kX0, 0.002);
  EXPECT_NEAR(x1, kX1, 0.002);
  EXPECT_NEAR(z0, kZ0, 0.002);
  EXPECT_NEAR(z1, kZ1, 0.002);
  std::printf("the hole [%.2f, %.2f] x [%.2f, %.2f]; its portal [%.3f, %.3f] x [%.3f, %.3f]\n", kX0, kX1, kZ0, kZ1, x0,
              x1, z0, z1);
}

TEST(SeenWindows, APlaceSeenThroughTheHoleIsBeyondItALampOnItsWallIsNot) {
  // What the estimate does not try as a lamp: clipped blobs triangulated out beyond a window.
  const RayTracer scene(Wall(true));
  int clipped = 0;
  const std::vector<View> views{FrontViewOfTheHole(&clipped)};
  ASSERT_GT(clipped, 100);
  const std::vector<SeenWindow> seen = SeenWindows(views, scene);
  ASSERT_EQ(seen.size(), 1u);
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ(), middle(0.5 * (kX0 + kX1), kWallY, 0.5 * (kZ0 + kZ1));
  EXPECT_TRUE(BeyondAWindow(seen, middle + Eigen::Vector3d(0, 2.5, 0.3), up));  // out there, through the hole
  EXPECT_TRUE(BeyondAWindow(seen, middle + Eigen::Vector3d(1.0, 1.5, 0), up));  // seen obliquely through it
  EXPECT_FALSE(BeyondAWindow(seen, middle + Eigen::Vector3d(0, -1.0, 0), up));  // in the room
  EXPECT_FALSE(BeyondAWindow(seen, middle + Eigen::Vector3d(-1.2, 0.1, 0), up));  // a sconce on the wall
  EXPECT_FALSE(BeyondAWindow(seen, middle + Eigen::Vector3d(-3.0, 1.0, 0), up));  // behind the wall, off the hole's cone
  // From a little before the wall (the window's own blobs triangulated: its pane's light, not
  // a bulb's): at the hole, yes; on the wall beside it, or farther into the room, no.
  EXPECT_TRUE(BeyondAWindow(seen, middle + Eigen::Vector3d(0.1, -0.2, 0), up, -kBeyondWindow));
  EXPECT_FALSE(BeyondAWindow(seen, middle + Eigen::Vector3d(0.1, -0.2, 0), up));
  EXPECT_FALSE(BeyondAWindow(seen, middle + Eigen::Vector3d(-1.2, -0.1, 0), up, -kBeyondWindow));
  EXPECT_FALSE(BeyondAWindow(seen, middle + Eigen::Vector3d(0, -0.4, 0), up, -kBeyondWindow));
  // (a sconce 15 cm before the wall, 10 cm past the hole's edge: a lamp still)
  EXPECT_FALSE(BeyondAWindow(seen, middle + Eigen::Vector3d(0.5 * (kX1 - kX0) + 0.1, -0.15, 0), up, -kBeyondWindow));
}

TEST(SeenWindows, AHoleBesideARoomsCornerIsAWindow) {
  // A side wall 12 cm beyond the hole's right edge, reaching into the room, and the hole large
  // in view: the circle around the blob meets the side wall as much as the hole's own wall
  // (not one flat wall: refused); the ring just outside the blob (near_scale) meets its wall.
  Mesh mesh = Wall(true);
  const float side = static_cast<float>(kX1 + 0.12);
  Mesh wall = Quad({side, -1.0f, 0.0f}, {side, -1.0f, 3.0f}, {side, float(kWallY), 3.0f}, {side, float(kWallY), 0.0f});
  ComputeVertexNormals(&wall);
  mesh.Append(wall);
  const RayTracer scene(std::move(mesh));
  std::vector<View> views{BlankView(LookAt({0.45, 0.9, 1.4}, {0.6, kWallY, 1.4}, 160, 120, 70))};
  ASSERT_GT(ClipOff(&views[0], [](const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
              return ThroughWall(o, d, kX0, kX1, kZ0, kZ1);
            }), 2000);
  SeenWindowOptions circle_only;
  circle_only.near_scale = 0;  // (a ring 2 pixels from the blob's middle: its rays leave the scene)
  EXPECT_TRUE(SeenWindows(views, scene, circle_only).empty());
  const std::vector<SeenWindow> seen = SeenWindows(views, scene);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_NEAR(seen[0].normal.y(), -1, 1e-6) << seen[0].normal.transpose();
  EXPECT_NEAR(seen[0].centre.y(), kWallY, 1e-6);
  const Portal p = PortalAround(seen[0].outline, seen[0].centre, seen[0].normal, Eigen::Vector3d::UnitX());
  EXPECT_NEAR(p.centre.x() - p.half_u, kX0, 0.01);
  EXPECT_NEAR(p.centre.x() + p.half_u, kX1, 0.01);
  EXPECT_NEAR(p.centre.z() - p.half_v, kZ0, 0.01);
  EXPECT_NEAR(p.centre.z() + p.half_v, kZ1, 0.01);
}

TEST(SeenWindows, AWindowSeenInPartsFromTwoViewsIsOneWindow) {
  // One view sees the whole hole clipped, the other only its left third (the rest below the
  // clip level): the third alone is a window too, its centre farther from the whole's than
  // `merge` (made 5 cm here: the scans' windows seen in part lie 32 cm off, 30 by default);
  // it lies within the whole's outline on one wall: one window, the whole's.
  const RayTracer scene(Wall(true));
  const double third = (kX1 - kX0) / 3;
  std::vector<View> views{BlankView(LookAt({0.3, -1, 1.3}, {0.5, kWallY, 1.3}, 160, 120, 60)),
                          BlankView(LookAt({0.7, -1, 1.3}, {0.5, kWallY, 1.3}, 160, 120, 60))};
  for (int k = 0; k < 2; ++k) {
    const double x1 = k == 0 ? kX1 : kX0 + third;
    ASSERT_GT(ClipOff(&views[k], [&](const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
                return ThroughWall(o, d, kX0, x1, kZ0, kZ1);
              }), 100);
  }
  SeenWindowOptions o;
  o.merge = 0.05;
  const std::vector<SeenWindow> whole = SeenWindows({views[0]}, scene, o), part = SeenWindows({views[1]}, scene, o);
  ASSERT_EQ(whole.size(), 1u);
  ASSERT_EQ(part.size(), 1u);
  EXPECT_GT((whole[0].centre - part[0].centre).norm(), o.merge);
  const std::vector<SeenWindow> seen = SeenWindows(views, scene, o);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].pixels, whole[0].pixels);
  // The left and the right thirds first (neither within the other's outline: two windows),
  // then the whole: one window whatever the order.
  View right = views[1];
  ASSERT_GT(ClipOff(&right, [&](const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
              return ThroughWall(o, d, kX1 - third, kX1, kZ0, kZ1);
            }), 100);
  EXPECT_EQ(SeenWindows({views[1], right}, scene, o).size(), 2u);
  const std::vector<SeenWindow> all = SeenWindows({views[1], right, views[0]}, scene, o);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].pixels, whole[0].pixels);
}

TEST(SeenWindows, ASillBelowTheHoleDoesNotMoveItsWall) {
  // A sill 15 cm deep under the hole: some of the ring's rays meet its front, off the wall's
  // plane; the wall is fitted again without them, so the window lies on the wall itself.
  Mesh mesh = Wall(true);
  const float front = static_cast<float>(kWallY - 0.15), x0 = static_cast<float>(kX0 - 0.1),
              x1 = static_cast<float>(kX1 + 0.1), z = static_cast<float>(kZ0);
  Mesh sill = Quad({x0, front, z - 0.15f}, {x0, front, z}, {x1, front, z}, {x1, front, z - 0.15f});
  sill.Append(Quad({x0, front, z}, {x0, float(kWallY), z}, {x1, float(kWallY), z}, {x1, front, z}));
  ComputeVertexNormals(&sill);
  mesh.Append(sill);
  const RayTracer scene(std::move(mesh));
  int clipped = 0;
  const std::vector<View> views{FrontViewOfTheHole(&clipped)};
  ASSERT_GT(clipped, 100);
  const std::vector<SeenWindow> seen = SeenWindows(views, scene);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_NEAR(seen[0].centre.y(), kWallY, 1e-6) << seen[0].centre.transpose();
  EXPECT_NEAR(seen[0].normal.y(), -1, 1e-6) << seen[0].normal.transpose();
}

TEST(SeenWindows, AWindowOfFourPanesIsOneWindow) {
  // The hole split by a cross of mullions 6 cm wide (the depth camera sees them): four blobs
  // a few pixels apart, the mean pixel's ray on the cross. One window, the hole's extent.
  constexpr double kBar = 0.03, kXm = 0.5 * (kX0 + kX1), kZm = 0.5 * (kZ0 + kZ1);
  Mesh mesh = Wall(true);
  const float y = static_cast<float>(kWallY);
  const auto bar = [&](double x0, double x1, double z0, double z1) {
    return Quad({float(x0), y, float(z0)}, {float(x0), y, float(z1)}, {float(x1), y, float(z1)}, {float(x1), y, float(z0)});
  };
  Mesh cross = bar(kXm - kBar, kXm + kBar, kZ0, kZ1);
  cross.Append(bar(kX0, kXm - kBar, kZm - kBar, kZm + kBar));
  cross.Append(bar(kXm + kBar, kX1, kZm - kBar, kZm + kBar));
  ComputeVertexNormals(&cross);
  mesh.Append(cross);
  const RayTracer scene(std::move(mesh));
  std::vector<View> views{BlankView(LookAt({0.3, -1, 1.3}, {0.5, kWallY, 1.3}, 160, 120, 60))};
  const auto through_a_pane = [&](const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
    SurfacePoint hit;
    return ThroughWall(o, d, kX0, kX1, kZ0, kZ1) && !scene.Intersect(o, d, &hit);
  };
  ASSERT_GT(ClipOff(&views[0], through_a_pane), 100);
  const std::vector<SeenWindow> seen = SeenWindows(views, scene);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_NEAR(seen[0].normal.y(), -1, 1e-6);
  const Portal p = PortalAround(seen[0].outline, seen[0].centre, seen[0].normal, Eigen::Vector3d::UnitX());
  EXPECT_LT(p.centre.x() - p.half_u, kX0 + 0.01);
  EXPECT_GT(p.centre.x() + p.half_u, kX1 - 0.01);
  EXPECT_LT(p.centre.z() - p.half_v, kZ0 + 0.01);
  EXPECT_GT(p.centre.z() + p.half_v, kZ1 - 0.01);
}

TEST(SeenWindows, ABulbBeforeAWallIsNotAWindow) {
  // Clipped pixels off the mesh whose rays meet the wall behind them: a bulb that returned no
  // depth (the lamps' to place, SeenLamps), not a hole.
  const RayTracer scene(Wall(false));
  std::vector<View> views{BlankView(LookAt({0.3, -1, 1.3}, {0.5, kWallY, 1.3}, 160, 120, 60))};
  const Eigen::Vector3d bulb(0.5, 0.5, 1.4);
  ASSERT_GT(ClipOff(&views[0], [&](const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
              const Eigen::Vector3d to = bulb - o;
              return (to - to.dot(d) * d).norm() < 0.08;
            }), 20);
  EXPECT_TRUE(SeenWindows(views, scene).empty());
}

TEST(SeenWindows, ABrightSkyAboveAWallsTopIsNotAWindow) {
  // The rays leave the scene, but half the ring around the blob leaves it too: no wall rings it.
  Mesh wall = Wall(false);
  const RayTracer scene(std::move(wall));
  std::vector<View> views{BlankView(LookAt({0.3, -1, 2.6}, {0.5, kWallY, 3.0}, 160, 120, 60))};
  ASSERT_GT(ClipOff(&views[0], [](const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
              return ThroughWall(o, d, 0.1, 0.9, 3.0, 3.6);
            }), 100);
  EXPECT_TRUE(SeenWindows(views, scene).empty());
  SeenWindowOptions loose;  // (what refuses it: the ring, of which about half meets the wall)
  loose.min_rim_share = 0.3;
  EXPECT_EQ(SeenWindows(views, scene, loose).size(), 1u);
}

// The light a map sends through a window, against closed forms: a uniform sky of radiance L
// through a hole of area A sends pi L A whatever the wall's facing (a diffuse pane's power);
// a sky lit only within 41 degrees of the way out sends L A pi sin^2(41 deg) (a cap's
// projected solid angle); light from the room's side of the wall sends nothing.
TEST(SeenWindows, TheLightThroughAWindowIsItsClosedForm) {
  Portal w;
  w.half_u = 0.4, w.half_v = 0.35;
  const EnvMap env(91, Eigen::Vector3d::UnitZ());
  for (const Eigen::Vector3d& inward : {Eigen::Vector3d(0, -1, 0), Eigen::Vector3d(0.3, 0.5, -0.2).normalized(),
                                       Eigen::Vector3d(0, 0, -1)}) {
    std::vector<double> uniform(3 * env.size()), cap(3 * env.size(), 0.0), behind(3 * env.size(), 0.0);
    for (int j = 0; j < env.size(); ++j) {
      for (int c = 0; c < 3; ++c) uniform[3 * j + c] = 2.0 + c;
      if (env.direction(j).dot(-inward) > std::cos(41 * M_PI / 180)) cap[3 * j] = 2.0;
      if (env.direction(j).dot(inward) > 0) behind[3 * j + 1] = 5.0;
    }
    const Eigen::Vector3d all = PowerThrough(w, inward, env, uniform), some = PowerThrough(w, inward, env, cap),
                          none = PowerThrough(w, inward, env, behind);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(all[c], M_PI * (2.0 + c) * w.Area(), 1e-3 * all[c]) << c;
    const double sin41 = std::sin(41 * M_PI / 180);
    // (the cap's edge falls across cells: 91 rings, cells of 2 degrees)
    EXPECT_NEAR(some.x(), 2.0 * w.Area() * M_PI * sin41 * sin41, 0.01 * some.x());
    std::printf("cap: %.4f, closed form %.4f\n", some.x(), 2.0 * w.Area() * M_PI * sin41 * sin41);
    EXPECT_EQ(some.y(), 0.0);
    EXPECT_NEAR(none.y(), 0.0, 1e-3);  // (only cells across the wall's plane)
  }
}

}  // namespace
}  // namespace lp
