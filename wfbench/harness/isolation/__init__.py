"""Running someone else's policy apart: the sandbox, its child, the pipe protocol between them, and packages.

- :mod:`~wfbench.harness.isolation.sandbox`: the policy in a separate process inside
  bubblewrap, behind the guard's interface (docs/leaderboard.md, "The sandbox");
- :mod:`~wfbench.harness.isolation.child`: what runs inside it;
- :mod:`~wfbench.harness.isolation.wire`: the messages on the two pipes;
- :mod:`~wfbench.harness.isolation.package`: a policy folder packed into an archive and
  checked back out of one.
"""
