"""Tiny hand-made motion files whose answers are worked out by hand."""

TINY_ASF = """\
# two bones, lengths in inches (units length 1)
:version 1.10
:name tiny
:units
  mass 1.0
  length 1.0
  angle deg
:documentation
  hand-made
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name a
     direction 1 0 0
     length 10
     axis 0 0 0 XYZ
    dof rz
    limits (-180 180)
  end
  begin
     id 2
     name b
     direction 1 0 0
     length 10
     axis 0 0 90 XYZ
    dof rx
    limits (-180 180)
  end
:hierarchy
  begin
    root a
    a b
  end
"""

# Frame 1: a turned 90 deg about z, b straight. Frame 2: b also 90 deg about its local x,
# which (axis z 90) is the world y axis. Root moved 10 in = 0.254 m along x in frame 2.
TINY_AMC = """\
#!OML:ASF tiny.asf
:FULLY-SPECIFIED
:DEGREES
1
root 0 0 0 0 0 0
a 90
b 0
2
root 10 0 0 0 0 0
a 90
b 90
"""

# One root and one joint with channels in ZXY order; a quarter turn about z on the root
# and about x on the joint.
TINY_BVH = """\
HIERARCHY
ROOT hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT knee
  {
    OFFSET 0 -50 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 -50 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 100 0 0 0 0 0 0 0
10 100 0 90 0 0 0 90 0
"""
