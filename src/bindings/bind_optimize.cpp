// SurfMesh bindings — SurfaceMesh.optimize(): smoothing and untangling with a cancellable
// Python progress callback.
#include "arrays.h"
#include "handle.h"
#include "surfmesh/optimize/optimizer.h"

#include <pybind11/functional.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <stdexcept>
#include <string>

namespace surfmesh::bindings {

py::dict statsToDict(const QualityStats& s);

void bind_optimize(MeshClass& cls) {
  const OptimizeOptions kDefaults;
  // The one source of the options' defaults on the Python side (SurfMesh.app.options):
  // a default-constructed OptimizeOptions, by optimize()'s keyword names.
  cls.def_static(
      "optimize_defaults",
      []() {
        const OptimizeOptions o;
        py::dict d;
        d["measure"] = o.measure;
        d["max_sweeps"] = o.maxSweeps;
        d["rel_tol"] = o.relTol;
        d["move_tol"] = o.moveTol;
        d["inner_iterations"] = o.innerIterations;
        d["max_line_search"] = o.maxLineSearch;
        d["over_relaxation"] = o.overRelaxation;
        d["delta_policy"] = o.deltaPolicy;
        d["delta_epsilon"] = o.deltaEpsilon;
        d["delta"] = o.delta;
        d["monotone"] = o.monotone;
        d["threads"] = o.threads;
        return d;
      },
      "The defaults of optimize()'s options (the core's OptimizeOptions), by its keyword names: "
      "measure, max_sweeps, rel_tol, move_tol, inner_iterations, max_line_search, "
      "over_relaxation, delta_policy, delta_epsilon, delta, monotone, threads.");
  cls.def(
      "optimize",
      [](MeshHandle& h, const std::string& measure, int max_sweeps, double rel_tol, double move_tol,
         int inner_iterations, int max_line_search, double over_relaxation,
         const std::string& delta_policy, double delta_epsilon, double delta, bool monotone,
         int threads, py::object progress, py::object before, py::object fixed) {
        OptimizeOptions o;
        o.measure = measure;
        o.maxSweeps = max_sweeps;
        o.relTol = rel_tol;
        o.moveTol = move_tol;
        o.innerIterations = inner_iterations;
        o.maxLineSearch = max_line_search;
        o.overRelaxation = over_relaxation;
        o.deltaPolicy = delta_policy;
        o.deltaEpsilon = delta_epsilon;
        o.delta = delta;
        o.monotone = monotone;
        o.threads = threads;
        o.fixedNodes = toMask(fixed, static_cast<py::ssize_t>(h.get().nodeCount()), "fixed");
        if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
          throw std::invalid_argument("progress must be callable or None");
        // The callback runs on the calling thread after each sweep (GIL released around the
        // sweeps): it takes the GIL, and a Python exception cancels the run and is re-raised.
        std::unique_ptr<py::error_already_set> pyError;
        ProgressCallback cb;
        if (!progress.is_none()) {
          cb = [&](const OptimizeProgress& p) -> bool {
            py::gil_scoped_acquire gil;
            try {
              py::dict d;
              d["sweep"] = p.sweep;
              d["max_sweeps"] = p.maxSweeps;
              d["objective"] = p.objective;
              d["tangled"] = p.tangled;
              d["min_quality"] = p.minQuality;
              d["delta"] = p.delta;
              py::object r = progress(d);
              return r.is_none() || r.cast<bool>();
            } catch (py::error_already_set& e) {
              pyError = std::make_unique<py::error_already_set>(std::move(e));
              return false;
            }
          };
        }
        SurfaceMesh& mesh = h.get();
        // The caller's measure of the mesh as it is (the "stats" of measure(measure)): not
        // measured again.
        QualityStats given;
        const bool haveBefore = !before.is_none();
        if (haveBefore) {
          const py::dict b = py::cast<py::dict>(before);
          given.min = b["min"].cast<double>();
          given.max = b["max"].cast<double>();
          given.mean = b["mean"].cast<double>();
          given.stddev = b["std"].cast<double>();
          given.tangled = b["tangled"].cast<std::size_t>();
          given.elements = b["elements"].cast<std::size_t>();
          if (b.contains("across")) given.across = b["across"].cast<std::size_t>();
          if (given.elements != mesh.elementCount())
            throw std::invalid_argument("before: stats of " + std::to_string(given.elements) +
                                        " elements for a mesh of " +
                                        std::to_string(mesh.elementCount()));
        }
        OptimizeResult r;
        {
          py::gil_scoped_release release;
          r = optimizeMesh(mesh, o, cb, haveBefore ? &given : nullptr);
        }
        if (pyError) throw std::move(*pyError);
        py::dict d;
        d["before"] = statsToDict(r.before);
        d["after"] = statsToDict(r.after);
        d["sweeps"] = r.sweeps;
        d["seconds"] = r.seconds;
        d["reason"] = std::string(stopReasonName(r.reason));
        d["initial_objective"] = r.initialObjective;
        d["final_objective"] = r.finalObjective;
        d["moved_nodes"] = r.movedNodes;
        d["threads"] = r.threadsUsed;
        d["patch_untanglings"] = r.patchUntanglings;
        d["straightened_elements"] = r.straightenedElements;
        d["tangled_unmovable"] = r.tangledUnmovable;
        d["tangled_movable"] = r.tangledMovable;
        d["warnings"] = r.warnings;
        return d;
      },
      // The core's defaults (OptimizeOptions), as optimize_defaults() gives them.
      py::arg("measure") = kDefaults.measure, py::arg("max_sweeps") = kDefaults.maxSweeps,
      py::arg("rel_tol") = kDefaults.relTol, py::arg("move_tol") = kDefaults.moveTol,
      py::arg("inner_iterations") = kDefaults.innerIterations,
      py::arg("max_line_search") = kDefaults.maxLineSearch,
      py::arg("over_relaxation") = kDefaults.overRelaxation,
      py::arg("delta_policy") = kDefaults.deltaPolicy,
      py::arg("delta_epsilon") = kDefaults.deltaEpsilon, py::arg("delta") = kDefaults.delta,
      py::arg("monotone") = kDefaults.monotone, py::arg("threads") = kDefaults.threads,
      py::arg("progress") = py::none(), py::arg("before") = py::none(),
      py::arg("fixed") = py::none(),
      "Optimizes the mesh in place (nodes stay on their surfaces); the options' defaults are "
      "the core's. progress(dict) is called "
      "after every sweep; returning False cancels (reason 'cancelled', mesh unchanged). "
      "Returns a dict: before, after (stats), sweeps, seconds, reason, moved_nodes, threads, "
      "patch_untanglings (escapes of stuck tangled elements by joint relaxation tried), "
      "straightened_elements (tangled high-order triangles untangled by straight sides in "
      "(u,v)), "
      "tangled_unmovable / tangled_movable (ids of the elements left tangled without / with a "
      "movable node) and warnings (a line for each non-empty list). before: the stats dict of "
      "measure(measure) on the mesh as it is, when the caller has it (not measured again). "
      "fixed: None or a bool per node, True for the nodes the run leaves where they are.");
}

}  // namespace surfmesh::bindings
