#!/usr/bin/env python3
"""Meshes built to be hard for a grid tracer, as OBJ files, for `gridrt verify` (docs/ACCURACY.md,
"Meshes built to be hard"). No scene of data/ is like them; none is used to tune anything.

  python3 tools/hostile_meshes.py OUT_DIR
  for m in OUT_DIR/*.obj; do gridrt verify $m --traversal exact -n 1000; done

  soup       3,000 random intersecting triangles in a 2-unit box
  needles    2,000 triangles up to 3 units long and 1e-4 wide, in every direction
  scalemix   a floor 2e4 wide under 3,000 triangles 2e-3 wide
  uvsphere   a closed UV sphere of 40,000 triangles (slivers at its poles)
  coplanar   1,000 triangles in one plane, a third duplicated, a fifth duplicated reversed
  lattice    axis-aligned quads on a 12^3 lattice: faces on the planes of a regular grid
  flat       2,000 triangles in the plane z = 0.5: a grid one cell deep
  tjunction  40 x 40 squares, three triangles round the midpoint of each lower edge: T-junctions
  faraway    2,000 triangles 5 cm wide about 3.7e6 from the origin
  slivers    a strip of 800 triangles 1 unit long and 1/400 wide
  cone300    300 slivers round one apex (a cone: apex angle 1.2 degrees)
  prisms     300 closed triangular prisms 1e-3 wide and about 3.2 long, crossing at the origin
             (their faces' vertices a thousand times farther from a launch point near the
             origin than the point's own coordinates)
"""
import math
import os
import random
import sys
out = sys.argv[1]
os.makedirs(out, exist_ok=True)
def write(name, V, F):
    with open(os.path.join(out, name + ".obj"), "w") as f:
        for v in V: f.write("v %.9g %.9g %.9g\n" % v)
        for t in F: f.write("f %d %d %d\n" % (t[0]+1, t[1]+1, t[2]+1))
R = random.Random(7)
# 1 random intersecting soup
V=[];F=[]
for i in range(3000):
    c=[R.uniform(-1,1) for _ in range(3)]
    for k in range(3): V.append(tuple(c[j]+R.uniform(-.1,.1) for j in range(3)))
    F.append((3*i,3*i+1,3*i+2))
write("soup", V, F)
# 2 needles
V=[];F=[]
for i in range(2000):
    a=[R.uniform(-1,1) for _ in range(3)]; b=[R.uniform(-1,1) for _ in range(3)]
    e=[R.uniform(-1e-4,1e-4) for _ in range(3)]
    V += [tuple(a), tuple(b), tuple(a[j]+e[j] for j in range(3))]
    F.append((3*i,3*i+1,3*i+2))
write("needles", V, F)
# 3 scale mix: big floor + tiny triangles
V=[(-1e4,0,-1e4),(1e4,0,-1e4),(1e4,0,1e4),(-1e4,0,1e4)];F=[(0,1,2),(0,2,3)]
for i in range(3000):
    c=[R.uniform(-1,1),R.uniform(0.001,1),R.uniform(-1,1)]
    n=len(V)
    for k in range(3): V.append(tuple(c[j]+R.uniform(-1e-3,1e-3) for j in range(3)))
    F.append((n,n+1,n+2))
write("scalemix", V, F)
# 4 icosphere-ish UV sphere fine
V=[];F=[]
N=200;M=100
for i in range(M+1):
    th=math.pi*i/M
    for j in range(N):
        ph=2*math.pi*j/N
        V.append((math.sin(th)*math.cos(ph), math.cos(th), math.sin(th)*math.sin(ph)))
for i in range(M):
    for j in range(N):
        a=i*N+j;b=i*N+(j+1)%N;c=(i+1)*N+j;d=(i+1)*N+(j+1)%N
        F.append((a,c,b));F.append((b,c,d))
write("uvsphere", V, F)
# 5 coplanar overlapping duplicates (z-fight) + exact duplicates
V=[];F=[]
for i in range(1000):
    x=R.uniform(-1,1);z=R.uniform(-1,1);s=R.uniform(0.05,0.3)
    n=len(V)
    V += [(x,0,z),(x+s,0,z),(x,0,z+s)]
    F.append((n,n+1,n+2))
    if i%3==0: F.append((n,n+1,n+2))
    if i%5==0: F.append((n,n+2,n+1))
write("coplanar", V, F)
# 6 axis-aligned quads on a regular lattice (faces on cell boundaries)
V=[];F=[]
K=12
for ax in range(3):
    for s in range(K+1):
        for u in range(K):
            for w in range(K):
                if R.random()<0.7: continue
                def P(a,b):
                    p=[0,0,0]; p[ax]=s/K; p[(ax+1)%3]=a/K; p[(ax+2)%3]=b/K; return tuple(p)
                n=len(V); V+=[P(u,w),P(u+1,w),P(u+1,w+1),P(u,w+1)]
                F+=[(n,n+1,n+2),(n,n+2,n+3)]
write("lattice", V, F)
# 7 flat scene: everything in one plane z=0.5
V=[];F=[]
for i in range(2000):
    c=[R.uniform(-1,1),R.uniform(-1,1)]
    n=len(V)
    for k in range(3): V.append((c[0]+R.uniform(-.05,.05), c[1]+R.uniform(-.05,.05), 0.5))
    F.append((n,n+1,n+2))
write("flat", V, F)
# 8 T-junction grid of fans (many vertices on edges), and fine strip
V=[];F=[]
for i in range(40):
    for j in range(40):
        x=i/40;y=j/40;h=1/40
        n=len(V)
        V += [(x,y,0),(x+h,y,0),(x+h,y+h,0),(x,y+h,0),(x+h/2,y,0)]
        F += [(n,n+4,n+3),(n+4,n+2,n+3),(n+4,n+1,n+2)]
write("tjunction", V, F)
# 9 huge coordinates offset, tiny object
V=[];F=[]
for i in range(2000):
    c=[3e6+R.uniform(0,1),-2e6+R.uniform(0,1),1e6+R.uniform(0,1)]
    n=len(V)
    for k in range(3): V.append(tuple(c[j]+R.uniform(-.05,.05) for j in range(3)))
    F.append((n,n+1,n+2))
write("faraway", V, F)
# 10 a closed box of long slivers (fan around every face centre? no: strips)
V=[];F=[]
N=400
for j in range(N+1):
    V.append((j/N,0,0)); V.append((j/N,1,1e-3*(j%2)))
for j in range(N):
    a=2*j;b=2*j+1;c=2*j+2;d=2*j+3
    F += [(a,c,b),(b,c,d)]
write("slivers", V, F)
# 11 a fan of 300 slivers round one apex
N = 300
V = [(0, 0, 1)] + [(math.cos(2 * math.pi * k / N), math.sin(2 * math.pi * k / N), 0) for k in range(N)]
F = [(0, k + 1, (k + 1) % N + 1) for k in range(N)]
write("cone300", V, F)
# 12 closed triangular prisms 1e-3 wide, about 3.2 long, through the origin in random directions
V = []; F = []
for i in range(300):
    while True:
        d = [R.uniform(-1, 1) for _ in range(3)]
        n = math.sqrt(sum(c * c for c in d))
        if 0.2 < n <= 1: break
    d = [c / n for c in d]
    a = [1.0, 0.0, 0.0] if abs(d[0]) < 0.6 else [0.0, 1.0, 0.0]
    u = [d[1]*a[2]-d[2]*a[1], d[2]*a[0]-d[0]*a[2], d[0]*a[1]-d[1]*a[0]]
    un = math.sqrt(sum(c * c for c in u)); u = [c / un for c in u]
    w = [d[1]*u[2]-d[2]*u[1], d[2]*u[0]-d[0]*u[2], d[0]*u[1]-d[1]*u[0]]
    c0 = [R.uniform(-0.02, 0.02) for _ in range(3)]
    r = 0.5e-3 / math.cos(math.pi / 6)
    b = len(V)
    for end in (-1.6, 1.6):
        for k in range(3):
            ang = 2 * math.pi * k / 3
            V.append(tuple(c0[j] + end * d[j] + r * (math.cos(ang) * u[j] + math.sin(ang) * w[j]) for j in range(3)))
    F += [(b, b+2, b+1), (b+3, b+4, b+5)]
    for k in range(3):
        k1 = (k + 1) % 3
        F += [(b+k, b+k1, b+3+k1), (b+k, b+3+k1, b+3+k)]
write("prisms", V, F)
