// Structured diagnostics: the placeholders of a diagnostic's text, filled by hand-written
// expectations.
#include "surfmesh/diagnostic.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

using surfmesh::Diagnostic;
using surfmesh::InputError;

TEST(Diagnostic, RendersIdsListsAndNumbers) {
  Diagnostic d;
  d.code = "example";
  d.count = 3;
  d.nodes = {12, 5, 7, 9};
  d.elements = {40};
  d.faces = {0, 4};
  d.edges = {2};
  d.vertices = {6};
  d.values = {{"distance", 0.125}, {"total", 1234567.0}, {"tiny", 1.0 / 3.0}};
  d.format =
      "{count} of {total} nodes: worst {node} at {distance} ({tiny}); e.g. nodes {nodes1}; all "
      "{nodes}; element {element} on {face} and {face1} (faces {faces}), {edge}, {vertex}";
  EXPECT_EQ(d.render(),
            "3 of 1234567 nodes: worst 12 at 0.125 (0.333333); e.g. nodes 5 7 9; all 12 5 7 9; "
            "element 40 on Face1 and Face5 (faces Face1 Face5), Edge3, Vertex7");
}

TEST(Diagnostic, LeavesWhatItCannotFillAsItIs) {
  Diagnostic d;
  d.nodes = {1};
  d.format = "{node3} {element} {unknown} {nodes} {";
  EXPECT_EQ(d.render(), "{node3} {element} {unknown} 1 {");
}

TEST(Diagnostic, InputErrorSaysTheRenderedText) {
  Diagnostic d;
  d.code = "repeated_node";
  d.elements = {3};
  d.nodes = {8};
  d.format = "element {element} repeats node {node}";
  try {
    throw InputError(d);
  } catch (const std::invalid_argument& e) {  // callers that know only std::invalid_argument
    EXPECT_EQ(std::string(e.what()), "element 3 repeats node 8");
  }
  const InputError e(d);
  EXPECT_EQ(e.diagnostic().code, "repeated_node");
  EXPECT_EQ(e.diagnostic().elements[0], 3);
}

TEST(Diagnostic, CodesAreDistinctAndSaid) {
  std::set<std::string> seen;
  for (const surfmesh::DiagnosticCode& c : surfmesh::kDiagnosticCodes) {
    EXPECT_TRUE(seen.insert(c.code).second) << c.code;
    EXPECT_GT(std::string(c.meaning).size(), 10u) << c.code;
  }
  EXPECT_EQ(seen.count(surfmesh::code::kNodesOffShape), 1u);
}
