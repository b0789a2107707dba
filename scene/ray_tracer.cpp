#include "scene/ray_tracer.h"

#include "common/parallel.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <embree3/rtcore.h>

#include "common/error.h"

namespace lp {

struct RayTracer::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

RayTracer::RayTracer(Mesh mesh) : RayTracer(std::move(mesh), {}) {}

RayTracer::RayTracer(Mesh mesh, const std::vector<std::uint8_t>& open)
    : impl_(std::make_unique<Impl>()), mesh_(std::move(mesh)) {
  LP_CHECK(!mesh_.triangles.empty(), "empty mesh");
  LP_CHECK(open.empty() || open.size() == mesh_.triangles.size(), "open: one flag per triangle");
  if (std::find(open.begin(), open.end(), 1) != open.end()) {
    open_ = open;
    for (std::size_t t = 0; t < open.size(); ++t)
      if (!open[t]) triangle_of_.push_back(static_cast<int>(t));
    LP_CHECK(!triangle_of_.empty(), "every triangle open");
  }
  LP_CHECK(mesh_.normals.size() == mesh_.positions.size(), "mesh lacks normals (call SanitizeMesh)");
  BoundingSphere(mesh_, &center_, &radius_);
  epsilon_ = 1e-5 * radius_;

  // No "threads=N" here: with the TBB tasking system that would cap the whole process.
  impl_->device = rtcNewDevice(nullptr);
  LP_CHECK(impl_->device, "rtcNewDevice failed: " << rtcGetDeviceError(nullptr));
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), mesh_.positions.size()));
  for (std::size_t i = 0; i < mesh_.positions.size(); ++i)
    for (int c = 0; c < 3; ++c) v[3 * i + c] = mesh_.positions[i][c];
  const std::size_t prims = triangle_of_.empty() ? mesh_.triangles.size() : triangle_of_.size();
  auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                             3 * sizeof(unsigned), prims));
  for (std::size_t i = 0; i < prims; ++i) {
    const Eigen::Vector3i& t = mesh_.triangles[triangle_of_.empty() ? i : triangle_of_[i]];
    for (int c = 0; c < 3; ++c) idx[3 * i + c] = static_cast<unsigned>(t[c]);
  }
  rtcCommitGeometry(geom);
  rtcAttachGeometry(impl_->scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(impl_->scene);
  LP_CHECK(rtcGetDeviceError(impl_->device) == RTC_ERROR_NONE, "Embree BVH build failed");
}

RayTracer::~RayTracer() = default;

namespace {
/// An Embree ray from `o` along `d` over (tnear, tfar), with no hit yet.
RTCRayHit RayHit(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float tnear, float tfar) {
  RTCRayHit rh;
  rh.ray.org_x = o.x(), rh.ray.org_y = o.y(), rh.ray.org_z = o.z();
  rh.ray.dir_x = d.x(), rh.ray.dir_y = d.y(), rh.ray.dir_z = d.z();
  rh.ray.tnear = tnear;
  rh.ray.tfar = tfar;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.ray.time = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}
}  // namespace

std::int64_t RayTracer::CountHits(const std::vector<std::pair<Eigen::Vector3f, Eigen::Vector3f>>& rays) const {
  std::vector<std::int64_t> hits((rays.size() + 4095) / 4096, 0);
  ParallelForChunks(0, rays.size(), 4096, [&](std::size_t lo, std::size_t hi) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    std::int64_t n = 0;
    for (std::size_t i = lo; i < hi; ++i) {
      const auto& [o, d] = rays[i];
      RTCRayHit rh = RayHit(o, d, static_cast<float>(epsilon_), 1e30f);
      rtcIntersect1(impl_->scene, &ctx, &rh);
      n += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
    hits[lo / 4096] = n;
  });
  std::int64_t total = 0;
  for (std::int64_t h : hits) total += h;
  return total;
}

bool RayTracer::Intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, SurfacePoint* hit,
                          double tmax) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh = RayHit(o.cast<float>(), d.cast<float>(), static_cast<float>(epsilon_),
                        static_cast<float>(std::min(tmax, 1e30)));
  rtcIntersect1(impl_->scene, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  const int prim = triangle_of_.empty() ? static_cast<int>(rh.hit.primID) : triangle_of_[rh.hit.primID];
  const Eigen::Vector3i& t = mesh_.triangles[prim];
  const double u = rh.hit.u, v = rh.hit.v, w = 1 - u - v;
  hit->triangle = prim;
  hit->distance = rh.ray.tfar;
  hit->position = o + d * static_cast<double>(rh.ray.tfar);
  const Eigen::Vector3d p0 = mesh_.positions[t[0]].cast<double>();
  Eigen::Vector3d ng = (mesh_.positions[t[1]].cast<double>() - p0).cross(mesh_.positions[t[2]].cast<double>() - p0);
  ng.normalize();
  if (ng.dot(d) > 0) ng = -ng;
  Eigen::Vector3d ns = (w * mesh_.normals[t[0]] + u * mesh_.normals[t[1]] + v * mesh_.normals[t[2]]).cast<double>();
  const double len = ns.norm();
  ns = len > 1e-12 ? Eigen::Vector3d(ns / len) : ng;
  if (ns.dot(ng) < 0) ns = -ns;  // flipped or inconsistent normals: shade the side that is seen
  hit->geometric = ng;
  hit->shading = ns;
  hit->albedo = (w * mesh_.albedo[t[0]] + u * mesh_.albedo[t[1]] + v * mesh_.albedo[t[2]]).cast<double>();
  return true;
}

namespace {

/// An Embree shadow ray from `o` along `d`, t in (tnear, tfar).
RTCRay ShadowQuery(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float tnear, float tfar) {
  RTCRay ray;
  ray.org_x = o.x();
  ray.org_y = o.y();
  ray.org_z = o.z();
  ray.dir_x = d.x();
  ray.dir_y = d.y();
  ray.dir_z = d.z();
  ray.tnear = tnear;
  ray.tfar = tfar;
  ray.mask = 0xFFFFFFFFu;
  ray.flags = 0;
  ray.time = 0;
  return ray;
}

}  // namespace

bool RayTracer::Occluded(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double tmax) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay ray = ShadowQuery(o.cast<float>(), d.cast<float>(), static_cast<float>(epsilon_),
                           static_cast<float>(std::min(tmax, 1e30)));
  rtcOccluded1(impl_->scene, &ctx, &ray);
  return ray.tfar < 0;
}

void RayTracer::OccludedMany(const std::vector<ShadowRay>& rays, std::vector<std::uint8_t>* blocked) const {
  thread_local std::vector<RTCRay> stream;
  stream.resize(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i)
    stream[i] = ShadowQuery(rays[i].origin, rays[i].dir, static_cast<float>(epsilon_), rays[i].tmax);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  rtcOccluded1M(impl_->scene, &ctx, stream.data(), static_cast<unsigned>(stream.size()), sizeof(RTCRay));
  blocked->resize(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) (*blocked)[i] = stream[i].tfar < 0;
}

}  // namespace lp
