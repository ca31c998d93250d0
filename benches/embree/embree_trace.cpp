// Embree 3 reference for `propsim bench trace`: the same mesh (OBJ), the same rays (6
// little-endian f32 per ray), the same checksum (sum of hit triangle index + 1), closest hit
// and occlusion, single-ray queries on N threads, medians of 5 runs.
//   apt-get install libembree-dev
//   g++ -O3 -march=x86-64 -std=c++17 benches/embree/embree_trace.cpp -lembree3 -lpthread -o /tmp/embree_trace
//   propsim bench trace --write-inputs /tmp/terrain
//   /tmp/embree_trace /tmp/terrain.obj /tmp/terrain_coherent.bin /tmp/terrain_incoherent.bin
#include <embree3/rtcore.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

static double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int main(int argc, char** argv) {
  if (argc < 3) { std::fprintf(stderr, "usage: %s MESH.obj RAYS.bin...\n", argv[0]); return 2; }
  std::vector<float> v; std::vector<unsigned> f;
  std::ifstream obj(argv[1]); std::string line;
  while (std::getline(obj, line)) {
    std::istringstream s(line); std::string tag; s >> tag;
    if (tag == "v") { float x, y, z; s >> x >> y >> z; v.insert(v.end(), {x, y, z}); }
    else if (tag == "f") { unsigned a, b, c; s >> a >> b >> c; f.insert(f.end(), {a - 1, b - 1, c - 1}); }
  }
  unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  RTCDevice dev = rtcNewDevice(nullptr);
  double t0 = now();
  RTCScene scene = rtcNewScene(dev);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  float* vb = (float*)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), v.size() / 3);
  std::copy(v.begin(), v.end(), vb);
  unsigned* ib = (unsigned*)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), f.size() / 3);
  std::copy(f.begin(), f.end(), ib);
  rtcCommitGeometry(g); rtcAttachGeometry(scene, g); rtcReleaseGeometry(g);
  rtcCommitScene(scene);
  std::printf("embree %d.%d, %zu triangles, %u threads, build %.3f s\n", RTC_VERSION_MAJOR, RTC_VERSION_MINOR, f.size() / 3, threads, now() - t0);
  for (int a = 2; a < argc; ++a) {
    std::ifstream in(argv[a], std::ios::binary);
    in.clear(); in.seekg(0, std::ios::end); size_t bytes = in.tellg(); in.seekg(0);
    std::vector<float> rays(bytes / 4); in.read((char*)rays.data(), bytes);
    size_t n = rays.size() / 6;
    std::vector<uint32_t> hit(n);
    std::vector<uint8_t> occ(n);
    // EMBREE_STREAM=1: each thread traces contiguous batches of 256 rays with Embree's stream
    // API (rtcIntersect1M / rtcOccluded1M) instead of one rtcIntersect1 call per ray.
    const bool stream = std::getenv("EMBREE_STREAM") && std::string(std::getenv("EMBREE_STREAM")) == "1";
    const size_t batch = 256;
    auto make = [&](size_t i) {
      const float* q = &rays[6 * i];
      float len = std::sqrt(q[3] * q[3] + q[4] * q[4] + q[5] * q[5]);
      return RTCRay{q[0], q[1], q[2], 0.0f, q[3] / len, q[4] / len, q[5] / len, 0.0f, INFINITY, 0xFFFFFFFF, 0, 0};
    };
    auto run = [&](bool occlusion) {
      std::vector<std::thread> pool;
      for (unsigned t = 0; t < threads; ++t) pool.emplace_back([&, t] {
        RTCIntersectContext ctx; rtcInitIntersectContext(&ctx);
        if (stream) {
          std::vector<RTCRayHit> rh(batch);
          std::vector<RTCRay> rs(batch);
          for (size_t b0 = t * batch; b0 < n; b0 += threads * batch) {
            size_t m = std::min(batch, n - b0);
            if (occlusion) {
              for (size_t k = 0; k < m; ++k) rs[k] = make(b0 + k);
              rtcOccluded1M(scene, &ctx, rs.data(), m, sizeof(RTCRay));
              for (size_t k = 0; k < m; ++k) occ[b0 + k] = rs[k].tfar < 0.0f;
            } else {
              for (size_t k = 0; k < m; ++k) { rh[k] = RTCRayHit{}; rh[k].ray = make(b0 + k); rh[k].hit.geomID = RTC_INVALID_GEOMETRY_ID; }
              rtcIntersect1M(scene, &ctx, rh.data(), m, sizeof(RTCRayHit));
              for (size_t k = 0; k < m; ++k) hit[b0 + k] = rh[k].hit.geomID == RTC_INVALID_GEOMETRY_ID ? 0 : rh[k].hit.primID + 1;
            }
          }
          return;
        }
        for (size_t i = t; i < n; i += threads) {
          if (occlusion) {
            RTCRay ray = make(i);
            rtcOccluded1(scene, &ctx, &ray);
            occ[i] = ray.tfar < 0.0f;
          } else {
            RTCRayHit rh{};
            rh.ray = make(i);
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene, &ctx, &rh);
            hit[i] = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? 0 : rh.hit.primID + 1;
          }
        }
      });
      for (auto& p : pool) p.join();
    };
    std::vector<double> tc, to;
    for (int k = 0; k < 5; ++k) {
      double s = now(); run(false); tc.push_back(now() - s);
      s = now(); run(true); to.push_back(now() - s);
    }
    std::sort(tc.begin(), tc.end()); std::sort(to.begin(), to.end());
    uint64_t sum = 0, hits = 0, occluded = 0;
    for (size_t i = 0; i < n; ++i) { sum += hit[i]; hits += hit[i] != 0; occluded += occ[i]; }
    std::printf("%s%s: %zu rays, closest hit %.2f Mrays/s, occlusion %.2f Mrays/s, hits %llu, occluded %llu, checksum 0x%016llx\n",
                argv[a], stream ? " (stream API)" : "", n, n / tc[2] / 1e6, n / to[2] / 1e6, (unsigned long long)hits, (unsigned long long)occluded, (unsigned long long)sum);
  }
  rtcReleaseScene(scene); rtcReleaseDevice(dev);
}
