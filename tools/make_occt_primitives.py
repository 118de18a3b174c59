"""Writes data/occt_primitives.step: a sphere, a torus and a cone (each a solid of Open
CASCADE's primitives, placed apart) as Open CASCADE's STEP writer exports them (AP214), with
a pcurve for every edge on every face. Usage: make_occt_primitives.py OUT.step (needs
`pip install cadquery-ocp`)."""
import sys
from OCP.BRepPrimAPI import BRepPrimAPI_MakeSphere, BRepPrimAPI_MakeTorus, BRepPrimAPI_MakeCone
from OCP.BRep import BRep_Builder
from OCP.TopoDS import TopoDS_Compound
from OCP.STEPControl import STEPControl_Writer, STEPControl_AsIs
from OCP.Interface import Interface_Static
from OCP.gp import gp_Pnt, gp_Dir, gp_Ax2

builder = BRep_Builder()
compound = TopoDS_Compound()
builder.MakeCompound(compound)
frame = lambda x, y, z, dx=0.0, dy=0.0, dz=1.0: gp_Ax2(gp_Pnt(x, y, z), gp_Dir(dx, dy, dz))
# A sphere cut by its latitudes ±60° (two caps' planes and the zone between).
builder.Add(compound, BRepPrimAPI_MakeSphere(frame(0, 0, 0), 10.0, -1.0471975511965976, 1.0471975511965976).Shape())
# A torus tilted off the axes.
builder.Add(compound, BRepPrimAPI_MakeTorus(frame(40, 0, 0, 0.0, 0.6, 0.8), 12.0, 3.0).Shape())
# A truncated cone.
builder.Add(compound, BRepPrimAPI_MakeCone(frame(0, 40, 0), 8.0, 3.0, 15.0).Shape())
Interface_Static.SetCVal_s("write.step.schema", "AP214IS")
writer = STEPControl_Writer()
writer.Transfer(compound, STEPControl_AsIs)
writer.Write(sys.argv[1])
