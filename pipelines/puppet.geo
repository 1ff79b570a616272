// crom's puppet (Neural Modes §5): a torso with a head on a neck, two arms
// and two legs, flat in z so that each limb and the neck swing most easily
// forward and back (metres, y up, z forward)
SetFactory("OpenCASCADE");
Box(1) = {-0.15, -0.25, -0.1, 0.3, 0.5, 0.2};      // torso
Box(2) = {-0.05, 0.24, -0.02, 0.1, 0.1, 0.04};     // neck
Sphere(3) = {0, 0.44, 0, 0.11};                    // head
Box(4) = {-0.16, -0.8, -0.0225, 0.14, 0.56, 0.045}; // legs
Box(5) = {0.02, -0.8, -0.0225, 0.14, 0.56, 0.045};
Box(6) = {-0.6, 0.1, -0.0175, 0.46, 0.1, 0.035};    // arms
Box(7) = {0.14, 0.1, -0.0175, 0.46, 0.1, 0.035};
BooleanUnion{ Volume{1}; Delete; }{ Volume{2:7}; Delete; }
