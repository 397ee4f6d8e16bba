"""Accounts, logins, device credentials and the experimenters' assistance limits (issue #13)."""

from sessions.accounts.accounts import REFUSED, Accounts, Login, LoginFailed
from sessions.accounts.throttle import LoginThrottle
from sessions.accounts.watch import LoginWatch

__all__ = ["REFUSED", "Accounts", "Login", "LoginFailed", "LoginThrottle", "LoginWatch"]
