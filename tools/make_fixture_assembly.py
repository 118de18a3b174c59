"""Writes data/fixture_assembly.step: an assembly as Open CASCADE's XCAF STEP writer exports
one — a plate and a sub-assembly of two bolts (cylinders) placed twice, once turned 90°
about z, with product and instance names. Usage: make_fixture_assembly.py OUT.step
(needs `pip install cadquery-ocp`)."""
from OCP.XCAFApp import XCAFApp_Application
from OCP.TDocStd import TDocStd_Document
from OCP.TCollection import TCollection_ExtendedString
from OCP.XCAFDoc import XCAFDoc_DocumentTool
from OCP.STEPCAFControl import STEPCAFControl_Writer
from OCP.STEPControl import STEPControl_AsIs
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
from OCP.TopLoc import TopLoc_Location
from OCP.gp import gp_Trsf, gp_Vec, gp_Ax1, gp_Pnt, gp_Dir, gp_Ax2
from OCP.TDataStd import TDataStd_Name
from OCP.Interface import Interface_Static
import math

def name(label, text):
    TDataStd_Name.Set_s(label, TCollection_ExtendedString(text))

def place(dx, dy, dz, angle_deg=0.0):
    t = gp_Trsf()
    t.SetRotation(gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), math.radians(angle_deg))
    s = gp_Trsf(); s.SetTranslation(gp_Vec(dx, dy, dz))
    return TopLoc_Location(s.Multiplied(t))

doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
XCAFApp_Application.GetApplication_s().InitDocument(doc)
tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
plate = tool.AddShape(BRepPrimAPI_MakeBox(100.0, 60.0, 10.0).Shape(), False)
name(plate, "plate")
bolt = tool.AddShape(BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 4.0, 30.0).Shape(), False)
name(bolt, "bolt")
pair = tool.NewShape(); name(pair, "bolt pair")
name(tool.AddComponent(pair, bolt, place(0, 0, 0)), "bolt left")
name(tool.AddComponent(pair, bolt, place(20, 0, 0)), "bolt right")
top = tool.NewShape(); name(top, "fixture")
name(tool.AddComponent(top, plate, place(0, 0, 0)), "base plate")
name(tool.AddComponent(top, pair, place(30, 15, 10)), "front pair")
name(tool.AddComponent(top, pair, place(70, 45, 10, 90.0)), "back pair")
tool.UpdateAssemblies()
Interface_Static.SetCVal_s("write.step.schema", "AP214IS")
w = STEPCAFControl_Writer(); w.SetNameMode(True)
w.Transfer(doc, STEPControl_AsIs)
w.Write(sys.argv[1])
