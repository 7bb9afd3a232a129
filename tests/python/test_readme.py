"""README.md and docs/: the README's Python sample runs and does what its comments say, its
command lines parse, its relative links (and those of docs/ and bench/) lead to files, and it
stays a short page (run: freecadcmd -t test_readme -M tests/python).

The sample is the first ```python block under the README's "Python start" heading. It runs in
a namespace of its own with the repository root as working directory. Its comments state what
``print(rep)`` and ``print(res)`` show ("N invalid (T tangled, A standing across)"): every such
count must be in the printed output, the input must be tangled and the result valid, with the
input's node and element ids kept.
"""

import contextlib
import glob
import io
import os
import re
import shlex
import unittest

import FreeCAD

import surfmesh_testing as T

README = os.path.join(T.REPO, "README.md")
MAX_README_LINES = 200
DOC_PAGES = ("python-api", "gui", "cli", "input-meshes", "method", "performance", "development")

_FENCE = re.compile(r"^```(\w*)\s*$")
_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
# A comment's counts: "N invalid (T tangled, A standing across)", or "T tangled, A standing
# across" alone (the torus example's invalid count depends on the Gmsh release that meshed it:
# its element standing across is also tangled on some, not on others).
_COUNTS = re.compile(r"(?:\d+ invalid \()?\d+ tangled, \d+ standing across")


def read(path):
    with open(path, encoding="utf-8") as fh:
        return fh.read()


def fenced_blocks(text):
    """[(heading, language, code)] of the fenced blocks of a Markdown text, with the last
    ``#``-heading above each."""
    blocks, heading, lang, code = [], "", None, None
    for line in text.splitlines():
        m = _FENCE.match(line)
        if code is None:
            if m:
                lang, code = m.group(1), []
            elif line.startswith("#"):
                heading = line.lstrip("#").strip()
        elif line.strip() == "```":
            blocks.append((heading, lang, "\n".join(code) + "\n"))
            code = None
        else:
            code.append(line)
    return blocks


def python_sample(text):
    """The first ```python block under the "Python start" heading."""
    for heading, lang, code in fenced_blocks(text):
        if heading.lower().startswith("python") and lang == "python":
            return code
    return None


def relative_links(text):
    """The link targets of a Markdown text outside its fenced blocks and code spans, without
    web addresses and in-page anchors."""
    prose, fenced = [], False
    for line in text.splitlines():
        if _FENCE.match(line) or line.strip() == "```":
            fenced = not fenced
            continue
        if not fenced:
            prose.append(re.sub(r"`[^`]*`", "", line))
    out = []
    for target in _LINK.findall("\n".join(prose)):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        out.append(target.split("#", 1)[0])
    return out


class ReadmePage(unittest.TestCase):
    def setUp(self):
        self.text = read(README)

    def test_readme_is_a_short_page(self):
        n = len(self.text.splitlines())
        self.assertLessEqual(n, MAX_README_LINES, f"README.md has {n} lines")
        for words in ("scripts/demo.sh", "scripts/test.sh"):
            self.assertIn(words, self.text)
            self.assertTrue(os.path.isfile(os.path.join(T.REPO, words)), words)

    def test_readme_links_every_docs_page(self):
        links = set(relative_links(self.text))
        for page in DOC_PAGES:
            path = f"docs/{page}.md"
            self.assertTrue(os.path.isfile(os.path.join(T.REPO, path)), f"{path} is missing")
            self.assertIn(path, links, f"README.md does not link {path}")

    def test_relative_links_lead_to_files(self):
        pages = [README] + sorted(glob.glob(os.path.join(T.REPO, "docs", "*.md")))
        pages += [os.path.join(T.REPO, "bench", "RESULTS.md")]
        pages += sorted(glob.glob(os.path.join(T.REPO, "bench", "history", "*.md")))
        checked, broken = 0, []
        for page in pages:
            for target in relative_links(read(page)):
                checked += 1
                path = os.path.normpath(os.path.join(os.path.dirname(page), target))
                if not os.path.exists(path):
                    broken.append(f"{os.path.relpath(page, T.REPO)}: {target}")
        self.assertGreater(checked, 20, "no links found: the link pattern is broken")
        self.assertEqual(broken, [], "links to missing files")

    def test_command_lines_parse(self):
        """Every `surfmesh optimize|measure|measures|batch` line of the README's shell blocks
        parses with the command's own argument parser (nothing is run)."""
        from SurfMesh.cli import batch, surfmesh_cli

        lines = [ln.split("#", 1)[0].strip() for _h, lang, code in fenced_blocks(self.text)
                 if lang == "sh" for ln in code.splitlines()]
        lines = [ln for ln in lines if ln.startswith("surfmesh ")]
        self.assertGreaterEqual(len(lines), 2, "the README shows no surfmesh command line")
        for ln in lines:
            argv = shlex.split(ln)[1:]
            with contextlib.redirect_stderr(io.StringIO()) as err:
                try:
                    if argv[0] == "batch":
                        batch.build_parser().parse_args(argv[1:])
                    else:
                        surfmesh_cli.build_parser("surfmesh").parse_args(argv)
                except SystemExit:
                    self.fail(f"README: {ln!r} does not parse: {err.getvalue().strip()}")
                except ValueError as exc:  # batch's parser raises instead of exiting
                    self.fail(f"README: {ln!r} does not parse: {exc}")


class ReadmePythonSample(unittest.TestCase):
    def setUp(self):
        self.docs_before = set(FreeCAD.listDocuments())

    def tearDown(self):
        for name in set(FreeCAD.listDocuments()) - self.docs_before:
            FreeCAD.closeDocument(name)

    def test_sample_runs_and_does_what_it_says(self):
        import SurfMesh

        code = python_sample(read(README))
        self.assertIsNotNone(code, "README.md has no ```python block under 'Python start'")
        ns = {"__name__": "readme_sample"}
        out = io.StringIO()
        cwd = os.getcwd()
        os.chdir(T.REPO)
        try:
            with contextlib.redirect_stdout(out):
                exec(compile(code, "README.md (Python start)", "exec"), ns)  # noqa: S102
        finally:
            os.chdir(cwd)
        printed = out.getvalue()

        rep, res, mesh = ns.get("rep"), ns.get("res"), ns.get("mesh")
        self.assertIsInstance(rep, SurfMesh.QualityReport, "the sample defines no report `rep`")
        self.assertIsInstance(res, SurfMesh.OptimizeResult, "the sample defines no result `res`")
        # The counts its comments show are those the sample prints.
        claims = [c for ln in code.splitlines() if "#" in ln
                  for c in _COUNTS.findall(ln.split("#", 1)[1])]
        self.assertGreaterEqual(len(claims), 2, "the sample's comments show no counts")
        for claim in claims:
            self.assertIn(claim, printed, f"the README says {claim!r}; the sample printed:\n"
                          f"{printed}")
        # What the sample is about: a tangled input, a valid result, the ids kept.
        self.assertGreater(rep.stats["tangled"], 0)
        self.assertEqual(res.before.stats["tangled"], rep.stats["tangled"])
        self.assertEqual(res.after.stats["invalid"], 0)
        self.assertEqual(res.after.stats["tangled"], 0)
        fem = mesh.FemMesh
        new = res.mesh
        self.assertEqual(new.NodeCount, fem.NodeCount)
        self.assertEqual(list(new.Nodes), list(fem.Nodes))
        self.assertEqual(list(new.Faces), list(fem.Faces))
        self.assertGreater(res.after.stats["min"], res.before.stats["min"])
        self.assertLess(res.after.stats["max_distance_to_shape"], 1e-9)
        # The input is unchanged; the document-level call made the object the comment names.
        self.assertEqual(SurfMesh.measure(mesh, ns["part"]).stats["tangled"],
                         rep.stats["tangled"])
        obj = ns.get("obj")
        named = re.search(r'"(\w+_optimized)"', code)
        self.assertIsNotNone(obj)
        self.assertIsNotNone(named, "the sample's comment names no optimized object")
        self.assertEqual(obj.Name, named.group(1))
        self.assertEqual(SurfMesh.stats_of(obj)["invalid"], 0)


if __name__ == "__main__":
    unittest.main()
