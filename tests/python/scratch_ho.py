import unittest, sys
sys.path.insert(0, "/work/main/tests/python")
import test_high_order as H
class S(H.GmshSideNodesOffTheirFace):
    def test_x(self):
        for name in ("occt_housing_bottom.brep", "occt_bottle.brep", "nist_pmi_1.step", "nist_pmi_2.step", "occt_screw.step"):
            try:
                self.check_placed(name)
            except Exception as e:
                print(name, "->", str(e)[:200])
