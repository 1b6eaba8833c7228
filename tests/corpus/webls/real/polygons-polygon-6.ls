delta=30
n=2
stemsize=0.01
axiom:[{+.G.{.&G.{.&G.][-G[&G[&G.].}.].}.}]
p1: A --> [&GA{.].
p2: B --> B&.G.}
p3: X(a) -> X(a+4.5)
