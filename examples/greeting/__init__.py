"""The paper's greeting application, written twice: plain rclpy and ContextROS.

Both print the local time and a greeting for the city the robot is in (Tokyo: JST and
Japanese; London: GMT and English). `plain_node.py` holds the context logic inline;
`context_node.py` takes the city from the Tokyo/London layers of `greeting.layers`.
"""
