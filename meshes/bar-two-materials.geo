// A 0.3 m x 0.05 m bar in two materials, for dolfrag's `geometry.kind = "file"`.
// Physical surfaces name the material groups ([materials.NAME] in a case),
// physical curves name the boundaries (load.boundary, supports). Lengths in metres.
Point(1) = {0, 0, 0};
Point(2) = {0.1, 0, 0};
Point(3) = {0.3, 0, 0};
Point(4) = {0.3, 0.05, 0};
Point(5) = {0.1, 0.05, 0};
Point(6) = {0, 0.05, 0};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 6};
Line(6) = {6, 1};
Line(7) = {2, 5};
Curve Loop(1) = {1, 7, 5, 6};
Plane Surface(1) = {1};
Curve Loop(2) = {2, 3, 4, -7};
Plane Surface(2) = {2};
Physical Surface("concrete") = {1};
Physical Surface("steel") = {2};
Physical Curve("left") = {6};
Physical Curve("right") = {3};
Physical Curve("bottom") = {1, 2};
Physical Curve("top") = {4, 5};
