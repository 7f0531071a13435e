// Two-room bunker (lengths in m, z up): a reinforced concrete block 4.6 m x 2.4 m x 2.2 m
// high holding two rooms 2.0 m x 2.0 m x 2.0 m side by side along x, walls and roof
// 0.2 m thick, an internal wall between the rooms with a 0.8 m x 2.0 m doorway, and a
// 0.9 m x 2.0 m door to the outside in the long wall at y = 0 of the first room.
// Physical groups, as dolfrag's geometry.kind = "file" reads them (docs/bunker.md):
//   volume  "concrete"  every cell
//   surface "inner"     every face of the two rooms and of the doorway between them
//   surface "ground"    z = 0, the base of the walls (clamped to the foundation)
//   surface "outer"     the rest of the outside, the outer door's sides included
SetFactory("OpenCASCADE");
t = 0.2;  L = 2.0;  H = 2.0;               // wall, room side, room height
X = 3 * t + 2 * L;  Y = 2 * t + L;
e = 1e-6;                                  // bounding-box tolerance

Box(1) = {0, 0, 0, X, Y, H + t};                        // the block
Box(2) = {t, t, 0, L, L, H};                            // room 1
Box(3) = {2 * t + L, t, 0, L, L, H};                    // room 2
Box(4) = {t + L, t + (L - 0.8) / 2, 0, t, 0.8, H};      // doorway through the internal wall
Box(5) = {t + (L - 0.9) / 2, 0, 0, 0.9, t, H};          // door to the outside, room 1
BooleanDifference(10) = { Volume{1}; Delete; }{ Volume{2, 3, 4, 5}; Delete; };

ground[] = Surface In BoundingBox{-e, -e, -e, X + e, Y + e, e};
inner[] = Surface In BoundingBox{t - e, t - e, -e, X - t + e, Y - t + e, H + e};
inner[] -= ground[];
all[] = Abs(Boundary{ Volume{10}; });
outer[] = all[];
outer[] -= inner[];
outer[] -= ground[];

Physical Volume("concrete") = {10};
Physical Surface("inner") = {inner[]};
Physical Surface("ground") = {ground[]};
Physical Surface("outer") = {outer[]};

// walls one or two elements thick: smooth and optimise away the slivers (docs/bunker.md)
Mesh.Smoothing = 5;
Mesh.OptimizeThreshold = 0.8;
