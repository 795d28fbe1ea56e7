"""Body kinds: their names and the codes ``World.kind (N,)`` stores (compare with these names,
never with raw numbers)."""
KINDS = ("static", "kinematic", "dynamic")
STATIC, KINEMATIC, DYNAMIC = 0, 1, 2
