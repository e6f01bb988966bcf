// The recorders of a run: one class per family of series, and the list (make_recorders).
#include "sim/recorder.h"

#include "analysis/metrics.h"
#include "analysis/pile_height.h"
#include "common/ice_formulas.h"
#include "common/state_archive.h"
#include "json/reader.h"
#include "io/run_file.h"
#include "parallel/comm.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

namespace hs::sim {

namespace {

/// Sum of a per-step vector quantity over an output interval; the row is its mean, or the
/// instantaneous value when no step was taken yet (row 0).
struct Mean3 {
  Vec3 sum = Vec3::Zero();
  Vec3 take(std::uint64_t n, const Vec3& instant) {
    const double inv = n ? 1.0 / static_cast<double>(n) : 0.0;
    const Vec3 m = n ? Vec3(sum * inv) : instant;
    sum.setZero();
    return m;
  }
};

// ---- /series/time, /series/step
class TimeRecorder : public Recorder {
 public:
  void declare(io::RunFile& f) override {
    id_time_ = f.add_series("/series/time", 1, "s", "simulated time");
    id_step_ = f.add_int_series("/series/step", 1, "1", "step number");
  }
  void write(Simulation& sim, io::RunFile& f) override {
    const double t = sim.engine().time();
    const auto st = static_cast<std::int64_t>(sim.engine().step_count());
    f.append(id_time_, &t);
    f.append(id_step_, &st);
    ++rows_;
  }
  void figures(RunFigures& fig) const override { fig.rows = rows_; }
  void save(StateArchive& a, const std::string& p) const override { a.put_value(p + "rows", rows_); }
  void load(const StateArchive& a, const std::string& p) override { rows_ = a.get_value<std::uint64_t>(p + "rows"); }

 private:
  int id_time_ = -1, id_step_ = -1;
  std::uint64_t rows_ = 0;
};

// ---- /series/walls/<name>/force; without a structure also /series/force (their total)
class WallsRecorder : public Recorder {
 public:
  WallsRecorder(const std::vector<scene::WallDef>& walls, bool total_is_force)
      : walls_(walls), total_(total_is_force), sum_(walls.size()), peak_(walls.size(), 0.0),
        peak_time_(walls.size(), 0.0) {}
  void declare(io::RunFile& f) override {
    if (total_)
      id_total_ = f.add_series("/series/force", 3, "N",
                               "total force exerted by the ice on all walls, mean over the output interval "
                               "ending at time");
    for (const auto& w : walls_)
      id_.push_back(f.add_series("/series/walls/" + w.name + "/force", 3, "N",
                                 "force on wall '" + w.name + "', mean over the output interval"));
  }
  void after_step(const Simulation& sim) override {
    const auto& e = sim.engine();
    for (std::size_t w = 0; w < walls_.size(); ++w) {
      const Vec3& f = e.wall_force(static_cast<int>(w));
      sum_[w].sum += f;
      const double m = f.norm();
      if (m > peak_[w]) {
        peak_[w] = m;
        peak_time_[w] = e.time();
      }
    }
    ++n_;
  }
  void write(Simulation& sim, io::RunFile& f) override {
    Vec3 total = Vec3::Zero();
    for (std::size_t w = 0; w < walls_.size(); ++w) {
      const Vec3 m = sum_[w].take(n_, sim.engine().wall_force(static_cast<int>(w)));
      total += m;
      f.append(id_[w], m.data());
    }
    if (total_) f.append(id_total_, total.data());
    n_ = 0;
  }
  void figures(RunFigures& fig) const override {
    fig.wall_peak = peak_;
    fig.wall_peak_time = peak_time_;
  }
  void save(StateArchive& a, const std::string& p) const override {
    a.put(p + "sum", sum_);
    a.put(p + "peak", peak_);
    a.put(p + "peak_time", peak_time_);
    a.put_value(p + "n", n_);
  }
  void load(const StateArchive& a, const std::string& p) override {
    a.get_into(p + "sum", sum_);
    a.get_into(p + "peak", peak_);
    a.get_into(p + "peak_time", peak_time_);
    n_ = a.get_value<std::uint64_t>(p + "n");
  }

 private:
  const std::vector<scene::WallDef>& walls_;
  bool total_;
  std::vector<Mean3> sum_;
  std::vector<double> peak_, peak_time_;
  std::vector<int> id_;
  int id_total_ = -1;
  std::uint64_t n_ = 0;
};

// ---- /series/force, /series/moment, /series/parts/<part>/{force,moment}: the structure's
// total load (particles + blocks, Simulation::structure_load)
class StructureLoadRecorder : public Recorder {
 public:
  explicit StructureLoadRecorder(const std::vector<std::string>& parts)
      : parts_(parts), pf_(parts.size()), pm_(parts.size()) {}
  void declare(io::RunFile& f) override {
    id_force_ = f.add_series("/series/force", 3, "N",
                             "force exerted by the ice on the structure, mean over the output interval ending at time");
    id_moment_ = f.add_series("/series/moment", 3, "N m",
                              "moment of the ice loads on the structure about its mesh origin (moving with it), "
                              "mean over the output interval");
    for (const auto& pn : parts_) {
      id_pf_.push_back(f.add_series("/series/parts/" + pn + "/force", 3, "N",
                                    "force on structure part '" + pn + "', mean over the output interval"));
      id_pm_.push_back(f.add_series("/series/parts/" + pn + "/moment", 3, "N m",
                                    "moment on structure part '" + pn + "' about the mesh origin, mean over the interval"));
    }
  }
  void after_step(const Simulation& sim) override {
    sim.structure_load(load_);
    const StructureLoad& L = load_;
    force_.sum += L.force;
    moment_.sum += L.moment;
    for (std::size_t q = 0; q < parts_.size(); ++q) {
      pf_[q].sum += L.part_force[q];
      pm_[q].sum += L.part_moment[q];
    }
    total_ += L.force;
    ++steps_;
    const double fh = std::hypot(L.force.x(), L.force.y());
    if (fh > peak_step_) {
      peak_step_ = fh;
      peak_step_time_ = sim.engine().time();
    }
    ++n_;
  }
  void write(Simulation& sim, io::RunFile& f) override {
    sim.structure_load(load_);
    const StructureLoad& L = load_;
    const Vec3 force = force_.take(n_, L.force), moment = moment_.take(n_, L.moment);
    f.append(id_force_, force.data());
    f.append(id_moment_, moment.data());
    for (std::size_t q = 0; q < parts_.size(); ++q) {
      const Vec3 pf = pf_[q].take(n_, L.part_force[q]), pm = pm_[q].take(n_, L.part_moment[q]);
      f.append(id_pf_[q], pf.data());
      f.append(id_pm_[q], pm.data());
    }
    const double fh = std::hypot(force.x(), force.y());
    if (fh > peak_h_) {
      peak_h_ = fh;
      peak_h_time_ = sim.engine().time();
    }
    n_ = 0;
  }
  void figures(RunFigures& fig) const override {
    fig.peak_h = peak_h_;
    fig.peak_h_time = peak_h_time_;
    fig.peak_step = peak_step_;
    fig.peak_step_time = peak_step_time_;
    fig.mean_force = steps_ ? Vec3(total_ / static_cast<double>(steps_)) : Vec3::Zero();
  }
  void save(StateArchive& a, const std::string& p) const override {
    a.put_value(p + "force", force_);
    a.put_value(p + "moment", moment_);
    a.put(p + "part_force", pf_);
    a.put(p + "part_moment", pm_);
    a.put_value(p + "total", total_);
    const std::uint64_t c[2] = {n_, steps_};
    a.put(p + "counts", std::vector<std::uint64_t>(c, c + 2));
    const double d[4] = {peak_h_, peak_h_time_, peak_step_, peak_step_time_};
    a.put(p + "peaks", std::vector<double>(d, d + 4));
  }
  void load(const StateArchive& a, const std::string& p) override {
    force_ = a.get_value<Mean3>(p + "force");
    moment_ = a.get_value<Mean3>(p + "moment");
    a.get_into(p + "part_force", pf_);
    a.get_into(p + "part_moment", pm_);
    total_ = a.get_value<Vec3>(p + "total");
    const auto c = a.get<std::uint64_t>(p + "counts");
    const auto d = a.get<double>(p + "peaks");
    if (c.size() != 2 || d.size() != 4) throw std::runtime_error("checkpoint: structure load recorder of another version");
    n_ = c[0];
    steps_ = c[1];
    peak_h_ = d[0];
    peak_h_time_ = d[1];
    peak_step_ = d[2];
    peak_step_time_ = d[3];
  }

 private:
  std::vector<std::string> parts_;
  StructureLoad load_;  ///< this step's, reused
  Mean3 force_, moment_;
  std::vector<Mean3> pf_, pm_;
  int id_force_ = -1, id_moment_ = -1;
  std::vector<int> id_pf_, id_pm_;
  std::uint64_t n_ = 0, steps_ = 0;
  Vec3 total_ = Vec3::Zero();
  double peak_h_ = 0.0, peak_h_time_ = 0.0, peak_step_ = 0.0, peak_step_time_ = 0.0;
};

// ---- /load_per_step/{time,force}: the structure's load of every DEM step (the value
// StructureLoadRecorder averages into its rows), so that the run metrics do not depend on the
// output interval. Due every step: one row of 4 doubles into RunFile's buffer, written at its
// flushes; nothing kept between steps, so a checkpoint needs nothing from it (its rows up to the
// checkpoint step are copied back by a restart). Under MPI the load is already reduced over the
// ranks every step (Engine::reduce_loads; the blocks' share is replicated): every rank appends
// the same rows and rank 0 writes them, as for /series.
class LoadPerStepRecorder : public Recorder {
 public:
  void declare(io::RunFile& f) override {
    const std::string g = kLoadPerStepGroup;
    id_time_ = f.add_series(g + "/time", 1, "s", "time at the end of each DEM step (step 1 first)");
    id_force_ = f.add_series(g + "/force", 3, "N",
                             "force exerted by the ice on the structure during each DEM step (particles + blocks)");
  }
  bool due(std::uint64_t, const Schedule&) const override { return true; }
  void write(Simulation& sim, io::RunFile& f) override {
    if (sim.engine().step_count() == 0) return;  // the initial row: no step yet
    sim.structure_load(load_);
    const double t = sim.engine().time();
    f.append(id_time_, &t);
    f.append(id_force_, load_.force.data());
  }

 private:
  StructureLoad load_;  ///< this step's, reused
  int id_time_ = -1, id_force_ = -1;
};

// ---- /series/pile_height, /series/structure_position
/// The largest value of a series and when it was reached; kept across a restart.
struct RunningMax {
  double value = 0.0, time = 0.0;
  void update(double v, double t) {
    if (v > value) {
      value = v;
      time = t;
    }
  }
  void save(StateArchive& a, const std::string& key) const { a.put(key, std::vector<double>{value, time}); }
  void load(const StateArchive& a, const std::string& key) {
    const auto d = a.get<double>(key);
    if (d.size() != 2) throw std::runtime_error("checkpoint: " + key + " of another version");
    value = d[0];
    time = d[1];
  }
};

class PileHeightRecorder : public Recorder {
 public:
  PileHeightRecorder(const analysis::PileProbe& probe, const par::Comm& comm) : probe_(probe), comm_(comm) {}
  void declare(io::RunFile& f) override {
    id_pile_ = f.add_series("/series/pile_height", 1, "m",
                            "highest ice above the waterline over the upstream half of the structure, within "
                            "its widest radius + one particle diameter of the axis");
    id_pos_ = f.add_series("/series/structure_position", 3, "m", "position of the structure's mesh origin");
  }
  void write(Simulation& sim, io::RunFile& f) override {
    probe_.axis_point = sim.structure_position();
    const auto& ps = sim.engine().particles();
    const double ph = comm_.max(analysis::pile_height(probe_, ps.x.data(), ps.radius.data(), ps.owned()));
    f.append(id_pile_, &ph);
    f.append(id_pos_, probe_.axis_point.data());
    max_.update(ph, sim.engine().time());
  }
  void figures(RunFigures& fig) const override {
    fig.max_pile = max_.value;
    fig.max_pile_time = max_.time;
  }
  void save(StateArchive& a, const std::string& p) const override { max_.save(a, p + "max"); }
  void load(const StateArchive& a, const std::string& p) override { max_.load(a, p + "max"); }

 private:
  analysis::PileProbe probe_;
  const par::Comm& comm_;
  int id_pile_ = -1, id_pos_ = -1;
  RunningMax max_;
};

// ---- /series/pile_height_mean: the ISO-consistent pile height (pier only)
class PileMeanRecorder : public Recorder {
 public:
  PileMeanRecorder(const analysis::PileBand& band, const par::Comm& comm) : band_(band), comm_(comm) {}
  void declare(io::RunFile& f) override {
    id_ = f.add_series("/series/pile_height_mean", 1, "m",
                       "ISO-consistent rubble pile height: the crest of the ice above the waterline in each of " +
                           std::to_string(band_.bins) + " strips across the waterline width (" +
                           json_fmt(2.0 * band_.half_width) + " m) upstream of the pier axis, up to " +
                           json_fmt(band_.reach) + " m ahead of it, averaged over the strips (docs/output.md)");
  }
  void write(Simulation& sim, io::RunFile& f) override {
    band_.axis_point = sim.structure_position();
    const auto& ps = sim.engine().particles();
    std::vector<double> crest = analysis::pile_crests(band_, ps.x.data(), ps.radius.data(), ps.owned());
    comm_.max(crest.data(), static_cast<int>(crest.size()));
    const double h = analysis::mean_crest(crest);
    f.append(id_, &h);
    max_.update(h, sim.engine().time());
  }
  void figures(RunFigures& fig) const override {
    fig.has_pile_mean = true;
    fig.max_pile_mean = max_.value;
    fig.max_pile_mean_time = max_.time;
  }
  void save(StateArchive& a, const std::string& p) const override { max_.save(a, p + "max"); }
  void load(const StateArchive& a, const std::string& p) override { max_.load(a, p + "max"); }

 private:
  analysis::PileBand band_;
  const par::Comm& comm_;
  int id_ = -1;
  RunningMax max_;
};

// ---- /pile_per_clock/{time,height_top,height_mean,slope_deg,porosity}: /series/pile_height,
// /series/pile_height_mean and the pile's slope and porosity (analysis/metrics.h, P1 and P2; pier
// only, NaN otherwise or without a pile) every kPileClock s, on a clock of its own,
// so that their peaks do not depend on the output interval. Rows at t = 0 and every
// pile_clock_every steps; none at a stop between two (Recorders::write_stop), so a restarted
// run's rows are an uninterrupted run's.
class PileClockRecorder : public Recorder {
 public:
  PileClockRecorder(const analysis::PileProbe& probe, std::optional<analysis::PileBand> band,
                    std::optional<analysis::PileShapeGrid> shape, std::uint64_t every, const par::Comm& comm)
      : probe_(probe), band_(std::move(band)), shape_(std::move(shape)), every_(every), comm_(comm) {}
  void declare(io::RunFile& f) override {
    const std::string g = kPileClockGroup;
    id_time_ = f.add_series(g + "/time", 1, "s", "simulated time, every " + json_fmt(kPileClock) + " s");
    id_top_ = f.add_series(g + "/height_top", 1, "m", "as /series/pile_height, every " + json_fmt(kPileClock) + " s");
    id_mean_ = f.add_series(g + "/height_mean", 1, "m",
                            "as /series/pile_height_mean (NaN without a pier), every " + json_fmt(kPileClock) + " s");
    const std::string grid = shape_ ? " (cells of " + json_fmt(shape_->cell) + " m up to " + json_fmt(shape_->ahead) +
                                          " m ahead of the cone face on the waterline, pile cells " +
                                          json_fmt(shape_->min_height) + " m above the water)"
                                    : std::string();
    id_slope_ = f.add_series(g + "/slope_deg", 1, "deg",
                             "rubble slope angle: least-squares slope of the pile's crest against the distance ahead "
                             "of the cone face" + grid + " (docs/metrics.md); NaN without a pile or a pier");
    id_porosity_ = f.add_series(g + "/porosity", 1, "1",
                                "pile porosity: 1 - particle volume / envelope volume (waterline to crest) over the "
                                "pile's cells" + grid + " (docs/metrics.md); NaN without a pile or a pier");
  }
  bool due(std::uint64_t k, const Schedule&) const override { return k % every_ == 0; }
  void write(Simulation& sim, io::RunFile& f) override {
    if (sim.engine().step_count() % every_ != 0) return;  // a stop between two ticks
    const auto& ps = sim.engine().particles();
    probe_.axis_point = sim.structure_position();
    const double t = sim.engine().time();
    const double top = comm_.max(analysis::pile_height(probe_, ps.x.data(), ps.radius.data(), ps.owned()));
    double mean = std::numeric_limits<double>::quiet_NaN();
    if (band_) {
      band_->axis_point = probe_.axis_point;
      std::vector<double> crest = analysis::pile_crests(*band_, ps.x.data(), ps.radius.data(), ps.owned());
      comm_.max(crest.data(), static_cast<int>(crest.size()));
      mean = analysis::mean_crest(crest);
    }
    analysis::PileShape shape{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
    if (shape_) {
      shape_->axis_point = probe_.axis_point;
      analysis::PileShapeCells c = analysis::pile_shape_cells(*shape_, ps.x.data(), ps.radius.data(), ps.owned());
      comm_.max(c.crest.data(), static_cast<int>(c.crest.size()));
      comm_.sum(c.volume.data(), static_cast<int>(c.volume.size()));
      shape = analysis::pile_shape(*shape_, c);
    }
    f.append(id_time_, &t);
    f.append(id_top_, &top);
    f.append(id_mean_, &mean);
    f.append(id_slope_, &shape.slope_deg);
    f.append(id_porosity_, &shape.porosity);
  }

 private:
  analysis::PileProbe probe_;
  std::optional<analysis::PileBand> band_;
  std::optional<analysis::PileShapeGrid> shape_;
  std::uint64_t every_;
  const par::Comm& comm_;
  int id_time_ = -1, id_top_ = -1, id_mean_ = -1, id_slope_ = -1, id_porosity_ = -1;
};

// ---- the blocks' and particles' mean speeds over the run's last kRestWindow seconds (the at-rest check)
/// Every block's mean speed over the run's last kRestWindow seconds: the length of the path it
/// made (|centre displacement| + rotation angle x half diagonal, summed over every rigid step of
/// the window) divided by the window (docs/bridge.md, "Relaxation"); and every particle's, the
/// path of its centre sampled at the same rigid steps, divided by the window. The instantaneous
/// speed of a block at rest can read a few cm/s for one rigid step when Bullet swaps a
/// load-carrying point of a full contact manifold (docs/rigid.md, "Manifold chatter": a 4e-5 rad
/// turn that stops the next step), and the particles bonded to it follow; over the window such a
/// step counts as what it is, a path of a few hundredths of a mm, while a block or particle that
/// moves at v for the window -- steadily, or back and forth (rocking, spinning, vibrating in its
/// bonds: a net displacement would read ~0 there) -- still reads v. Motion that reverses within
/// one rigid step (~1 ms) is undercounted for particles. Blocks converted and particles made in the
/// window are left out; a particle removed in it counts with the path it made. Every rank keeps
/// the whole sheet's positions and paths (gathered at each sample), so the figure and a
/// checkpoint's copy do not depend on the ranks. A restart inside the window with a checkpoint from
/// before these paths existed opens the window at the first step after the restart (the window is then shorter; its
/// length is reported).
class RestWindow {
 public:
  explicit RestWindow(const par::Comm& comm) : comm_(comm) {}
  /// After every DEM step, and at the initial row (a run shorter than the window opens it there).
  void after_step(const Simulation& sim) {
    const rigid::RigidWorld& world = *sim.hybrid().world();
    if (open_) {
      if (world.step_count() != rigid_steps_) sample(sim);
      return;
    }
    const auto& sc = sim.schedule();
    const std::uint64_t w = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(kRestWindow / sc.dt - 1e-9)));
    if (sim.engine().step_count() + w < sc.total_steps) return;
    open_ = true;
    t0_ = world.time();
    te0_ = sim.engine().time();
    rigid_steps_ = world.step_count();
    open_particles(sim.engine());
    blocks_.clear();
    for (const rigid::BlockId id : world.blocks()) {
      if (world.fixed(id)) continue;
      const Vec3 x = world.position(id);
      const Quat q = world.orientation(id);
      blocks_.push_back({static_cast<double>(id.index), static_cast<double>(id.generation), x.x(), x.y(), x.z(), q.w(),
                         q.x(), q.y(), q.z(), 0.0});
    }
  }
  /// At the last step (collective): the figures (RunFigures::rest_window, final_mean_block_speed,
  /// final_mean_particle_speed).
  void finish(const Simulation& sim) {
    const rigid::RigidWorld& world = *sim.hybrid().world();
    window_ = open_ ? world.time() - t0_ : 0.0;
    speed_ = particle_speed_ = 0.0;
    if (!(window_ > 0)) return;
    if (sample_step_ != sim.engine().step_count()) sample(sim);  // the particles' last stretch
    const double te = sim.engine().time() - te0_;
    for (std::size_t k = 0; k < path_.size() && te > 0; ++k) particle_speed_ = std::max(particle_speed_, path_[k] / te);
    for (const auto& b : blocks_)
      if (world.alive(block_id(b))) speed_ = std::max(speed_, b[9] / window_);
  }
  void figures(RunFigures& f) const {
    f.rest_window = window_;
    f.final_mean_block_speed = speed_;
    f.final_mean_particle_speed = particle_speed_;
  }
  void save(StateArchive& a, const std::string& p) const {
    a.put_value(p + "rest_path_open", static_cast<std::uint64_t>(open_));
    a.put(p + "rest_path_clock", std::vector<double>{t0_, te0_});
    a.put(p + "rest_path_steps", std::vector<std::uint64_t>{rigid_steps_, sample_step_});
    std::vector<double> flat;
    for (const auto& b : blocks_) flat.insert(flat.end(), b.begin(), b.end());
    a.put(p + "rest_path_blocks", flat);
    a.put(p + "rest_path_gids", gids_);
    a.put(p + "rest_path_x", x_);
    a.put(p + "rest_path_particles", path_);
  }
  void load(const StateArchive& a, const std::string& p) {
    // A checkpoint from before the paths (net displacements, "rest_open"; or before any window)
    // cannot give the path made before it: the window opens at the first step after the restart.
    if (!a.has(p + "rest_path_open")) return;
    open_ = a.get_value<std::uint64_t>(p + "rest_path_open") != 0;
    const auto clock = a.get<double>(p + "rest_path_clock");
    const auto steps = a.get<std::uint64_t>(p + "rest_path_steps");
    t0_ = clock.at(0);
    te0_ = clock.at(1);
    rigid_steps_ = steps.at(0);
    sample_step_ = steps.at(1);
    const auto flat = a.get<double>(p + "rest_path_blocks");
    blocks_.assign(flat.size() / 10, {});
    for (std::size_t k = 0; k < blocks_.size(); ++k) std::copy_n(flat.begin() + 10 * k, 10, blocks_[k].begin());
    gids_ = a.get<double>(p + "rest_path_gids");
    x_ = a.get<double>(p + "rest_path_x");
    path_ = a.get<double>(p + "rest_path_particles");
  }

 private:
  static rigid::BlockId block_id(const std::array<double, 10>& b) {
    return {static_cast<std::uint32_t>(b[0]), static_cast<std::uint32_t>(b[1])};
  }
  /// Every particle's global id and position, gathered from all ranks onto every rank.
  std::vector<std::array<double, 4>> gather_particles(const bonded::Engine& e) const {
    const auto& ps = e.particles();
    par::Bytes mine(ps.owned() * 4 * sizeof(double));
    for (std::size_t i = 0; i < ps.owned(); ++i) {
      const double r[4] = {static_cast<double>(ps.gid[i]), ps.x[i].x(), ps.x[i].y(), ps.x[i].z()};
      std::memcpy(mine.data() + i * sizeof(r), r, sizeof(r));
    }
    const par::Bytes all0 = comm_.gather(mine);
    const std::string all = comm_.broadcast(comm_.rank() == 0 ? std::string(all0.begin(), all0.end()) : std::string());
    std::vector<std::array<double, 4>> rec(all.size() / (4 * sizeof(double)));
    if (!rec.empty()) std::memcpy(static_cast<void*>(rec.data()), all.data(), rec.size() * 4 * sizeof(double));
    return rec;
  }
  void open_particles(const bonded::Engine& e) {
    auto rec = gather_particles(e);
    std::sort(rec.begin(), rec.end(), [](const auto& a, const auto& b) { return a[0] < b[0]; });
    gids_.resize(rec.size());
    x_.resize(3 * rec.size());
    path_.assign(rec.size(), 0.0);
    for (std::size_t k = 0; k < rec.size(); ++k) {
      gids_[k] = rec[k][0];
      std::copy_n(rec[k].begin() + 1, 3, x_.begin() + 3 * k);
    }
    sample_step_ = e.step_count();
  }
  /// One sample (collective): every block's and particle's path since the last one.
  void sample(const Simulation& sim) {
    const rigid::RigidWorld& world = *sim.hybrid().world();
    for (auto& b : blocks_) {
      const rigid::BlockId id = block_id(b);
      if (!world.alive(id)) continue;
      const Vec3 x = world.position(id);
      const Quat q = world.orientation(id);
      b[9] += (x - Vec3(b[2], b[3], b[4])).norm() + q.angularDistance(Quat(b[5], b[6], b[7], b[8])) * world.half_extents(id).norm();
      b[2] = x.x(), b[3] = x.y(), b[4] = x.z(), b[5] = q.w(), b[6] = q.x(), b[7] = q.y(), b[8] = q.z();
    }
    rigid_steps_ = world.step_count();
    for (const auto& r : gather_particles(sim.engine())) {
      const auto it = std::lower_bound(gids_.begin(), gids_.end(), r[0]);
      if (it == gids_.end() || *it != r[0]) continue;  // made in the window
      const std::size_t k = static_cast<std::size_t>(it - gids_.begin());
      double* xk = &x_[3 * k];
      path_[k] += std::hypot(r[1] - xk[0], r[2] - xk[1], r[3] - xk[2]);
      std::copy_n(r.begin() + 1, 3, xk);
    }
    sample_step_ = sim.engine().step_count();
  }

  const par::Comm& comm_;
  bool open_ = false;
  double t0_ = 0.0, te0_ = 0.0, window_ = 0.0, speed_ = 0.0, particle_speed_ = 0.0;
  std::uint64_t rigid_steps_ = 0, sample_step_ = 0;  ///< the rigid and DEM steps of the last sample
  /// Blocks: index, generation, pose at the last sample (position, orientation w x y z), path [m].
  std::vector<std::array<double, 10>> blocks_;
  std::vector<double> gids_, x_, path_;  ///< particles present at the opening: ids (sorted), last sampled positions, paths
};

// ---- /series/blocks/...: the rigid blocks
class BlocksRecorder : public Recorder {
 public:
  BlocksRecorder(bool has_structure, const par::Comm& comm) : has_structure_(has_structure), rest_(comm) {}
  void declare(io::RunFile& f) override {
    if (has_structure_)
      id_force_ = f.add_series("/series/blocks/structure_force", 3, "N",
                               "the rigid blocks' share of /series/force (contact impulses on the structure "
                               "per rigid step), mean over the output interval");
    id_ke_ = f.add_series("/series/blocks/kinetic_energy", 1, "J", "kinetic energy of the rigid blocks");
    id_count_ = f.add_int_series("/series/blocks/count", 1, "1", "rigid blocks (not yet converted)");
    id_conv_ = f.add_int_series("/series/blocks/conversions", 1, "1", "blocks converted into particles so far");
    id_joints_ = f.add_int_series("/series/blocks/joints_broken", 1, "1", "freeze joints between blocks broken");
    id_awake_ = f.add_int_series("/series/blocks/awake", 1, "1",
                                 "dynamic blocks stepped by the rigid world (all of them unless blocks.far_sleep puts "
                                 "still ones far from the action to sleep; docs/rigid.md, \"Far sleep\")");
  }
  void after_step(const Simulation& sim) override {
    if (has_structure_) force_.sum += sim.hybrid().structure_force();
    ++n_;
    rest_.after_step(sim);
  }
  void write(Simulation& sim, io::RunFile& f) override {
    const auto& h = sim.hybrid();
    if (has_structure_) {
      const Vec3 bf = force_.take(n_, h.structure_force());
      f.append(id_force_, bf.data());
    }
    const double ke = h.rigid_kinetic_energy();
    const auto nblk = static_cast<std::int64_t>(h.world()->block_count());
    const auto nconv = static_cast<std::int64_t>(h.report().conversions);
    const auto nj = static_cast<std::int64_t>(h.world()->broken_joint_count());
    const auto nawake = static_cast<std::int64_t>(h.world()->awake_count());
    f.append(id_ke_, &ke);
    f.append(id_count_, &nblk);
    f.append(id_conv_, &nconv);
    f.append(id_joints_, &nj);
    f.append(id_awake_, &nawake);
    n_ = 0;
    if (sim.engine().step_count() == 0) rest_.after_step(sim);  // the initial row: a run shorter than the window
    if (sim.engine().step_count() == sim.schedule().total_steps) rest_.finish(sim);
  }
  void figures(RunFigures& fig) const override { rest_.figures(fig); }
  void save(StateArchive& a, const std::string& p) const override {
    a.put_value(p + "force", force_);
    a.put_value(p + "n", n_);
    rest_.save(a, p);
  }
  void load(const StateArchive& a, const std::string& p) override {
    force_ = a.get_value<Mean3>(p + "force");
    n_ = a.get_value<std::uint64_t>(p + "n");
    rest_.load(a, p);
  }

 private:
  bool has_structure_;
  RestWindow rest_;
  Mean3 force_;
  std::uint64_t n_ = 0;
  int id_force_ = -1, id_ke_ = -1, id_count_ = -1, id_conv_ = -1, id_joints_ = -1, id_awake_ = -1;
};

// ---- /series/energy/...: the particles' energy terms
class EnergyRecorder : public Recorder {
 public:
  void declare(io::RunFile& f) override {
    for (auto& x : terms_) x.id = f.add_series(std::string("/series/energy/") + x.name, 1, "J", x.description);
  }
  void write(Simulation& sim, io::RunFile& f) override {
    const auto E = sim.engine().energy();
    const double v[] = {E.kinetic_translational + E.kinetic_rotational,
                        E.kinetic_translational,
                        E.kinetic_rotational,
                        E.gravity_potential,
                        E.buoyancy_potential,
                        E.bond_elastic,
                        E.contact_elastic,
                        E.total()};
    for (std::size_t k = 0; k < std::size(terms_); ++k) f.append(terms_[k].id, &v[k]);
  }

 private:
  struct Term {
    const char* name;
    const char* description;
    int id;
  };
  Term terms_[8] = {
      {"kinetic", "kinetic energy, translational + rotational", 0},
      {"kinetic_translational", "translational kinetic energy", 0},
      {"kinetic_rotational", "rotational kinetic energy", 0},
      {"gravity_potential", "gravitational potential energy (reference z = 0)", 0},
      {"buoyancy_potential", "buoyancy potential energy", 0},
      {"bond_elastic", "elastic energy in intact bonds", 0},
      {"contact_elastic", "elastic energy in contacts", 0},
      {"total", "sum of the above", 0},
  };
};

// ---- /series/max_overlap_ratio: how close the contacts come to the stability limit
class OverlapRecorder : public Recorder {
 public:
  explicit OverlapRecorder(const par::Comm& comm) : comm_(comm) {}
  void declare(io::RunFile& f) override {
    id_ = f.add_series("/series/max_overlap_ratio", 1, "1",
                       "largest contact overlap / particle radius over the steps since the previous row "
                       "(particle pairs, walls, structure, blocks): the figure stability.max_overlap_ratio limits");
  }
  void after_step(const Simulation& sim) override {
    row_ = std::max(row_, sim.engine().worst_overlap_ratio());
  }
  void write(Simulation& sim, io::RunFile& f) override {
    // Row 0 (no step yet): the initial forces' overlap.
    const double v = comm_.max(std::max(row_, sim.engine().worst_overlap_ratio()));
    f.append(id_, &v);
    max_.update(v, sim.engine().time());
    row_ = 0.0;
  }
  void figures(RunFigures& fig) const override {
    fig.max_overlap = max_.value;
    fig.max_overlap_time = max_.time;
  }
  // A checkpoint from before this series has neither: the run's peak then starts at the restart.
  void save(StateArchive& a, const std::string& p) const override {
    max_.save(a, p + "max");
    a.put(p + "row", std::vector<double>{row_});
  }
  void load(const StateArchive& a, const std::string& p) override {
    if (a.has(p + "max")) max_.load(a, p + "max");
    if (a.has(p + "row")) row_ = a.get<double>(p + "row").at(0);
  }

 private:
  const par::Comm& comm_;
  int id_ = -1;
  double row_ = 0.0;  ///< this rank's largest since the previous row
  RunningMax max_;
};

// ---- /series/bonds_broken, /series/bonds, /series/particles
class CountsRecorder : public Recorder {
 public:
  void declare(io::RunFile& f) override {
    id_broken_ = f.add_int_series("/series/bonds_broken", 1, "1", "bonds broken since the start");
    id_bonds_ = f.add_int_series("/series/bonds", 1, "1", "intact bonds");
    id_particles_ = f.add_int_series("/series/particles", 1, "1", "particles");
  }
  void write(Simulation& sim, io::RunFile& f) override {
    const auto& e = sim.engine();
    const auto broken = static_cast<std::int64_t>(e.stats().bonds_broken);
    const std::int64_t nb = e.global_bond_count();
    const std::int64_t np = e.global_particle_count();
    f.append(id_broken_, &broken);
    f.append(id_bonds_, &nb);
    f.append(id_particles_, &np);
  }

 private:
  int id_broken_ = -1, id_bonds_ = -1, id_particles_ = -1;
};

// ---- /snapshots/NNNNNN/...: every particle, every snapshot interval
class SnapshotRecorder : public Recorder {
 public:
  explicit SnapshotRecorder(const par::Comm& comm) : comm_(comm) {}
  void declare(io::RunFile&) override {}
  bool due(std::uint64_t k, const Schedule& sc) const override {
    return k % sc.snapshot_every == 0 || k == sc.total_steps;
  }
  void write(Simulation& sim, io::RunFile& f) override {
    auto& e = sim.engine();
    e.refresh_bond_counts();  // bonds may have broken on the neighbouring rank
    const auto& p = e.particles();
    const std::size_t n = p.owned();
    // This rank's rows: after the lower ranks' particles.
    const io::FieldSlice sl{comm_.exscan(n), static_cast<std::uint64_t>(e.global_particle_count())};
    f.begin_snapshot(e.time(), e.step_count());
    f.write_field("position", p.x.data()->data(), n, 3, "m", sl);
    f.write_field("velocity", p.v.data()->data(), n, 3, "m/s", sl);
    f.write_field("radius", p.radius.data(), n, 1, "m", sl);
    ibuf_.assign(p.bond_count.begin(), p.bond_count.begin() + n);
    f.write_field("bond_count", ibuf_.data(), n, 1, "1", sl);
    lbuf_.assign(p.gid.begin(), p.gid.begin() + n);
    f.write_field("global_id", lbuf_.data(), n, 1, "1", sl);
    f.end_snapshot();
    ++count_;
  }
  void figures(RunFigures& fig) const override { fig.snapshots = count_; }
  void save(StateArchive& a, const std::string& p) const override { a.put_value(p + "count", count_); }
  void load(const StateArchive& a, const std::string& p) override { count_ = a.get_value<std::uint64_t>(p + "count"); }

 private:
  const par::Comm& comm_;
  std::vector<std::int32_t> ibuf_;
  std::vector<std::int64_t> lbuf_;
  std::uint64_t count_ = 0;
};

analysis::PileProbe pile_probe(const Simulation& sim, const scene::Scene& s) {
  analysis::PileProbe probe;
  const Vec3& v = s.structure.velocity;
  probe.upstream = Vec3(v.x(), v.y(), 0.0).norm() > 0 ? Vec3(v.x(), v.y(), 0.0).normalized() : Vec3::UnitX();
  probe.reach = sim.structure_radius() + s.material.particle_diameter;
  probe.water_level = s.water.enabled ? s.water.level : 0.0;
  return probe;
}

/// The band of /series/pile_height_mean (analysis/pile_height.h): the waterline width of the
/// pier, from its axis up to the waterline radius + L_c ahead (L_c of the ISO sheet: the
/// lattice's thickness, the scene's E, nu, rho_w, |g|; the pile's toe lies well within it for
/// slopes above ~10 deg); where L_c is not defined (no gravity) up to the widest radius + D, as
/// /series/pile_height. Strips about one particle diameter wide.
analysis::PileBand pile_band(const Simulation& sim, const scene::Scene& s) {
  analysis::PileBand band;
  const Vec3& v = s.structure.velocity;
  band.upstream = Vec3(v.x(), v.y(), 0.0).norm() > 0 ? Vec3(v.x(), v.y(), 0.0).normalized() : Vec3::UnitX();
  band.half_width = 0.5 * s.structure.pier.waterline_diameter;
  band.water_level = s.water.enabled ? s.water.level : 0.0;
  const double D = s.material.particle_diameter;
  const double L_c = characteristic_length(s.material.youngs_modulus, sim.built().lattice_thickness, s.water.density,
                                           s.gravity.norm(), s.material.poisson_ratio);
  band.reach = std::isfinite(L_c) && L_c > 0 ? band.half_width + L_c : sim.structure_radius() + D;
  band.bins = static_cast<std::size_t>(std::max(1.0, std::ceil(2.0 * band.half_width / D)));
  return band;
}

/// The grid of the pile's slope and porosity (analysis/metrics.h, P1 and P2): cells one particle
/// diameter D across, from the cone face on the waterline up to one waterline diameter ahead (a
/// pile steeper than atan(h_r / w) ends within it); pile cells' crests more than D above the
/// water (the level sheet's freeboard is less).
analysis::PileShapeGrid pile_shape_grid(const scene::Scene& s) {
  analysis::PileShapeGrid g;
  const Vec3& v = s.structure.velocity;
  g.upstream = Vec3(v.x(), v.y(), 0.0).norm() > 0 ? Vec3(v.x(), v.y(), 0.0).normalized() : Vec3::UnitX();
  g.radius = 0.5 * s.structure.pier.waterline_diameter;
  g.ahead = s.structure.pier.waterline_diameter;
  g.cell = s.material.particle_diameter;
  g.min_height = s.material.particle_diameter;
  g.water_level = s.water.enabled ? s.water.level : 0.0;
  return g;
}

}  // namespace

std::uint64_t pile_clock_every(const Schedule& sc) {
  return std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(kPileClock / sc.dt)));
}

std::vector<std::unique_ptr<Recorder>> make_recorders(const Simulation& sim, const scene::Scene& s,
                                                      const par::Comm& comm) {
  const bool st = sim.has_structure();
  std::vector<std::unique_ptr<Recorder>> r;
  r.push_back(std::make_unique<TimeRecorder>());
  if (st) r.push_back(std::make_unique<StructureLoadRecorder>(sim.structure_parts()));
  r.push_back(std::make_unique<WallsRecorder>(s.walls, /*total_is_force=*/!st));
  if (st) r.push_back(std::make_unique<PileHeightRecorder>(pile_probe(sim, s), comm));
  if (st && s.structure.type == "pier") r.push_back(std::make_unique<PileMeanRecorder>(pile_band(sim, s), comm));
  if (sim.has_blocks()) r.push_back(std::make_unique<BlocksRecorder>(st, comm));
  r.push_back(std::make_unique<EnergyRecorder>());
  r.push_back(std::make_unique<CountsRecorder>());
  if (sim.schedule().snapshot_every) r.push_back(std::make_unique<SnapshotRecorder>(comm));  // last: after the row
  // After the snapshots: a checkpoint keys recorders by position, so the older ones keep theirs.
  r.push_back(std::make_unique<OverlapRecorder>(comm));
  if (st) r.push_back(std::make_unique<LoadPerStepRecorder>());
  if (st) {
    std::optional<analysis::PileBand> band;
    std::optional<analysis::PileShapeGrid> shape;
    if (s.structure.type == "pier") band = pile_band(sim, s);
    if (s.structure.type == "pier") shape = pile_shape_grid(s);
    r.push_back(
        std::make_unique<PileClockRecorder>(pile_probe(sim, s), band, shape, pile_clock_every(sim.schedule()), comm));
  }
  return r;
}

// ---- the last good state: a copy of the snapshot fields after every completed step, written
// as a snapshot when a later step fails (SimulationError). Checks run at the end of a step, after
// the state was advanced, so the failing step's own state is not trusted. Cost: one copy of
// ~61 bytes per owned particle per step (docs/output.md gives the measured figure).
class Recorders::LastGood {
 public:
  explicit LastGood(const par::Comm& comm) : comm_(comm) {}
  void keep(const Simulation& sim) {
    const auto& e = sim.engine();
    const auto& p = e.particles();
    const std::size_t n = p.owned();
    x_.assign(p.x.begin(), p.x.begin() + n);
    v_.assign(p.v.begin(), p.v.begin() + n);
    r_.assign(p.radius.begin(), p.radius.begin() + n);
    bc_.assign(p.bond_count.begin(), p.bond_count.begin() + n);
    gid_.assign(p.gid.begin(), p.gid.begin() + n);
    time_ = e.time();
    step_ = e.step_count();
    global_n_ = static_cast<std::uint64_t>(e.global_particle_count());
  }
  void write(io::RunFile& f) {
    const std::size_t n = x_.size();
    const io::FieldSlice sl{comm_.exscan(n), global_n_};
    f.begin_snapshot(time_, step_);
    f.write_field("position", x_.data()->data(), n, 3, "m", sl);
    f.write_field("velocity", v_.data()->data(), n, 3, "m/s", sl);
    f.write_field("radius", r_.data(), n, 1, "m", sl);
    const std::vector<std::int32_t> bc(bc_.begin(), bc_.end());
    f.write_field("bond_count", bc.data(), n, 1, "1", sl);
    const std::vector<std::int64_t> gid(gid_.begin(), gid_.end());
    f.write_field("global_id", gid.data(), n, 1, "1", sl);
    f.end_snapshot();
  }
  double time() const { return time_; }
  std::uint64_t step() const { return step_; }

 private:
  const par::Comm& comm_;
  std::vector<Vec3> x_, v_;
  std::vector<double> r_;
  std::vector<std::uint8_t> bc_;  // under MPI: as this rank last counted (no exchange per step)
  std::vector<GlobalId> gid_;
  double time_ = 0.0;
  std::uint64_t step_ = 0, global_n_ = 0;
};

Recorders::Recorders(const Simulation& sim, const scene::Scene& s, const par::Comm& comm)
    : list_(make_recorders(sim, s, comm)), last_good_(std::make_unique<LastGood>(comm)) {}

Recorders::~Recorders() = default;

void Recorders::declare(io::RunFile& file) {
  for (auto& r : list_) r->declare(file);
}

void Recorders::write_initial(Simulation& sim, io::RunFile& file) {
  for (auto& r : list_) r->write(sim, file);
  last_good_->keep(sim);
}

void Recorders::after_step(std::uint64_t k, Simulation& sim, io::RunFile& file) {
  for (auto& r : list_) r->after_step(sim);
  for (auto& r : list_)
    if (r->due(k, sim.schedule())) r->write(sim, file);
  last_good_->keep(sim);
}

void Recorders::write_stop(std::uint64_t k, Simulation& sim, io::RunFile& file) {
  for (auto& r : list_)
    if (!r->due(k, sim.schedule())) r->write(sim, file);
}

std::uint64_t Recorders::write_last_good(io::RunFile& file) {
  last_good_->write(file);
  return last_good_->step();
}

double Recorders::last_good_time() const { return last_good_->time(); }

void Recorders::save_state(StateArchive& a) const {
  a.put_value("recorders/count", static_cast<std::uint64_t>(list_.size()));
  for (std::size_t k = 0; k < list_.size(); ++k) list_[k]->save(a, "recorders/" + std::to_string(k) + "/");
}

void Recorders::load_state(const StateArchive& a, const Simulation& sim) {
  if (a.get_value<std::uint64_t>("recorders/count") != list_.size())
    throw std::runtime_error("checkpoint: the run has another set of output series");
  for (std::size_t k = 0; k < list_.size(); ++k) list_[k]->load(a, "recorders/" + std::to_string(k) + "/");
  last_good_->keep(sim);
}

RunFigures Recorders::figures() const {
  RunFigures f;
  for (const auto& r : list_) r->figures(f);
  return f;
}

}  // namespace hs::sim
